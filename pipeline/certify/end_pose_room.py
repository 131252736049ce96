"""The room the end poses leave: the largest clearance of a pose whose tip lies within the
endpoint tolerance of P1 (or P5), sampled.

A sampling, not a bound (the bound is ``pipeline.certify.endpoints``' infeasibility
certificate): every sampled pose is a pose of the family's elbow branch with its tip within
the tolerance, so the sampled room is at most the true room. It chooses where the certifiable
regression asks for the margin and where the strips of ``pipeline.certify.strip_split`` look
for the infeasibility contour; neither relies on it for soundness.
"""

from __future__ import annotations

import numpy as np

from pipeline.geometry.clearance import link_box_clearance
from pipeline.model.kinematics import inverse_kinematics_batch

#: Circles of tips (radii 0 to the tolerance) and angles on each.
ROOM_RINGS = 5
ROOM_ANGLES = 180
#: Obstacles per vectorised batch (memory: 900 tips each; 2,000 obstacles in one batch took 0.7 GB).
_CHUNK_OBSTACLES = 256

__all__ = ["ROOM_ANGLES", "ROOM_RINGS", "configuration_clearance", "end_pose_room_m"]


def configuration_clearance(
    theta: np.ndarray,
    sizes_m: np.ndarray,
    arm,
    centre_x_m: np.ndarray | None = None,
    top_y_m: np.ndarray | None = None,
) -> np.ndarray:
    """Analytic clearance [m] (both links) of configurations ``theta`` (n, 2) [rad] against the
    obstacles ``sizes_m`` (n, >= 2: L, W [m]) of ``arm``'s scene, centred at ``centre_x_m`` (n,)
    [m] with their far edge at ``top_y_m`` (n,) [m] (None: the scene's centre x, its far edge d);
    ``arm`` is anything with ``scene``, ``link_lengths_m`` and ``link_radii_m`` (coefficients, a
    range model)."""
    scene = arm.scene
    r = scene.corner_radius_m
    centre_x = _per_obstacle(centre_x_m, scene.centre_x_m, len(sizes_m))
    top_y = _per_obstacle(top_y_m, scene.top_y_m, len(sizes_m))
    center = np.stack([centre_x, top_y - sizes_m[:, 1] / 2], -1)
    half = np.stack([sizes_m[:, 0] / 2 - r, sizes_m[:, 1] / 2 - r], -1)
    links = link_box_clearance(theta, arm.link_lengths_m, arm.link_radii_m, center, half, r)
    return np.minimum(links[:, 0], links[:, 1])


def _per_obstacle(values: np.ndarray | None, scene_value: float, n: int) -> np.ndarray:
    """``values`` as an (n,) float array, or the scene's value n times where None."""
    if values is None:
        return np.full(n, float(scene_value))
    return np.broadcast_to(np.asarray(values, dtype=float).ravel(), (n,))


def end_pose_room_m(
    arm,
    length_m: np.ndarray,
    width_m: np.ndarray,
    tolerance_m: float,
    centre_x_m: np.ndarray | None = None,
    rings: int = ROOM_RINGS,
    angles: int = ROOM_ANGLES,
    top_y_m: np.ndarray | None = None,
) -> np.ndarray:
    """Sampled room at the ends [m], (n,): for each obstacle (centred at ``centre_x_m`` (n,) [m],
    None: the scene's centre x; its far edge at ``top_y_m`` (n,) [m], None: the scene's d; P1
    and P5 move with the centre, and with the far edge where the scene's y1 is d), the smaller over P1 and P5 of the
    largest clearance of a pose on the family's elbow branch whose tip lies within
    ``tolerance_m`` of that end point (tips on :data:`ROOM_RINGS` circles of radii up to the
    tolerance, :data:`ROOM_ANGLES` angles each, unless ``rings`` and ``angles`` say otherwise;
    analytic distance). ``arm``: anything with
    ``scene``, ``link_lengths_m``, ``link_radii_m`` and ``elbow`` (coefficients, a range model)."""
    lengths = np.asarray(length_m, dtype=float).ravel()
    widths = np.asarray(width_m, dtype=float).ravel()
    scene = arm.scene
    centres = _per_obstacle(centre_x_m, scene.centre_x_m, lengths.size)
    tops = _per_obstacle(top_y_m, scene.top_y_m, lengths.size)
    if lengths.size > _CHUNK_OBSTACLES:  # every obstacle's room is computed on its own: chunks change nothing
        return np.concatenate(
            [
                end_pose_room_m(
                    arm,
                    lengths[k : k + _CHUNK_OBSTACLES],
                    widths[k : k + _CHUNK_OBSTACLES],
                    tolerance_m,
                    centres[k : k + _CHUNK_OBSTACLES],
                    rings,
                    angles,
                    tops[k : k + _CHUNK_OBSTACLES],
                )
                for k in range(0, lengths.size, _CHUNK_OBSTACLES)
            ]
        )
    angle = np.linspace(0.0, 2.0 * np.pi, angles, endpoint=False)
    radius = np.linspace(0.0, tolerance_m, rings)
    offsets = np.stack([np.outer(radius, np.cos(angle)).ravel(), np.outer(radius, np.sin(angle)).ravel()], -1)
    room = np.full(lengths.size, np.inf)
    sizes = np.repeat(np.column_stack([lengths, widths]), offsets.shape[0], axis=0)  # the obstacle of each tip
    end_y = tops if scene.start_y_m is None else np.full(lengths.size, float(scene.y1_m))  # y1 = d or fixed
    for side in (1.0, -1.0):
        ends = np.stack([centres + side * (lengths / 2 + scene.start_dx_m), end_y], -1)
        tips = (ends[:, None, :] + offsets[None]).reshape(-1, 2)
        theta = inverse_kinematics_batch(tips, arm.link_lengths_m, arm.elbow)
        tip_count = offsets.shape[0]
        clearance = configuration_clearance(
            theta, sizes, arm, np.repeat(centres, tip_count), np.repeat(tops, tip_count)
        )
        room = np.minimum(room, clearance.reshape(lengths.size, tip_count).max(axis=1, initial=-np.inf))
    return room
