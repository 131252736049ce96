"""Offline range certificates of a coefficients file (layer between ``offline`` and ``online``).

For every (L, W) of the fitted range and every t in [0, T(L, W)]: a rigorous lower bound on the
clearance of both links, an upper bound on the endpoint errors, and an infeasibility
certificate for the margin at the endpoint tolerance, stored as a region map over a subpaving
(``subpaving``: cuts of one axis at a time; ``lookup``: its compiled tree and lookup).

* :func:`certify_range` (``range_certificate``): coefficients -> :class:`RegionMap`, its stages
  sharing one :class:`CertificateSettings` (``certificate_settings``);
* :class:`RegionMap` (``region_map``): ``cell_at`` / ``cells_at`` lookups, summary, JSON;
* :func:`fit_certifiable` (``certifiable_regression``): constraint generation towards a fit
  the certificate accepts.

Derivations: ``duration`` (T and its gradient), ``clearance_bound`` (the three lower bounds),
``endpoints`` (endpoint errors and infeasibility), ``search`` (branch and bound, one axis cut
per node),
``strip_split`` (the smallest cells astride a contour, cut along W; the infeasibility's
monotonicity in W). ``end_pose_room`` samples the room the end poses leave (a choice of where to
look, never a proof).

The package's ``__init__`` imports nothing: ``region_map`` (the map and its lookups) needs NumPy
only, and the online generator imports it without the certificate's Coal-based modules.
"""
