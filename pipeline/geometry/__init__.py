"""Geometry: link-to-obstacle clearance routes and the continuous-time clearance certificates."""
