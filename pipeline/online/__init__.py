"""The online stage: loading coefficients with their region map, the generator (coefficients +
(L, W) -> trajectory: NumPy and a Numba-compiled core), and, in their own modules, the arm check and
certify-or-repair (Pinocchio and Coal: ``arm_check``, ``repair``, ``batch_certify``).

This package's ``__init__`` imports nothing heavy, so that a controller-side program that only
generates needs NumPy and Numba only; the public API is :mod:`pipeline`.
"""
