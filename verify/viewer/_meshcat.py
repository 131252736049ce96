"""Meshcat, imported in one place with its import-time DeprecationWarning silenced.

meshcat 0.3.2 imports ``zmq.eventloop.ioloop``, which pyzmq >= 17 deprecates; the warning
is noise for our users and tests. Only the viewer modules import this.
"""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message="zmq.eventloop.ioloop is deprecated", category=DeprecationWarning)
    import meshcat
    import meshcat.geometry as mg
    import meshcat.transformations as mtf
    from meshcat.animation import Animation
    from pinocchio.visualize import MeshcatVisualizer

__all__ = ["Animation", "MeshcatVisualizer", "meshcat", "mg", "mtf"]
