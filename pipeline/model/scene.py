"""The scene of the paper: where the obstacle stands and how the path is laid around it.

All lengths in metres, speeds in metres per second. Defaults follow the paper and
``shared/paper/NOTES.md`` (y1 = y5 = d, v = 0.2 m/s).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from pipeline.validation import check_finite, check_non_negative, check_positive


@dataclass(frozen=True)
class Scene:
    """Fixed geometry and motion settings shared by every obstacle size.

    Attributes:
        top_y_m: d, the y of the obstacle's far edge [m]; footprint y in [d - W, d].
        start_y_m: y1 = y5, the height of the start and goal points [m]; None means d.
        speed_m_s: v, the end effector's constant speed along the path [m/s].
        margin_m: Safety margin between links and obstacle [m].
        corner_radius_m: Corner radius of the rounded obstacle [m].
        obstacle_height_m: Extent of the obstacle along z, centred on the arm's plane [m].
        start_dx_m: P1.x - L/2 [m] (paper: 0.12).
        approach_dx_m: P2.x - L/2 [m] (paper: 0.03).
        approach_dy_m: (d - W) - P2.y [m] (paper: 0.03).
        apex_dy_m: (d - W) - P3.y [m] (paper: 0.10).
    """

    top_y_m: float = 0.56
    start_y_m: float | None = None
    speed_m_s: float = 0.2
    margin_m: float = 0.01
    corner_radius_m: float = 0.01
    obstacle_height_m: float = 1.0
    start_dx_m: float = 0.12
    approach_dx_m: float = 0.03
    approach_dy_m: float = 0.03
    apex_dy_m: float = 0.10

    def __post_init__(self) -> None:
        check_finite("top_y_m", self.top_y_m)
        if self.start_y_m is not None:
            check_finite("start_y_m", self.start_y_m)
        check_positive("speed_m_s", self.speed_m_s)
        check_non_negative("margin_m", self.margin_m)
        check_non_negative("corner_radius_m", self.corner_radius_m)
        check_positive("obstacle_height_m", self.obstacle_height_m)
        check_positive("start_dx_m", self.start_dx_m)
        check_non_negative("approach_dx_m", self.approach_dx_m)
        check_non_negative("approach_dy_m", self.approach_dy_m)
        check_positive("apex_dy_m", self.apex_dy_m)

    @property
    def y1_m(self) -> float:
        """Height of the start and goal points P1, P5 [m] (d unless set)."""
        return self.top_y_m if self.start_y_m is None else self.start_y_m

    def to_dict(self) -> dict[str, float | None]:
        """Plain-JSON form, as stored in coefficients files."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> Scene:
        """Inverse of :meth:`to_dict`; unknown keys are ignored."""
        names = {f for f in cls.__dataclass_fields__}
        return cls(**{k: v for k, v in data.items() if k in names})

    def is_close(self, other: Scene) -> bool:
        """True if both scenes agree to 1e-12 in every field."""
        a, b = self.to_dict(), other.to_dict()
        return all(
            (a[k] is None and b[k] is None)
            or (a[k] is not None and b[k] is not None and math.isclose(a[k], b[k], abs_tol=1e-12))
            for k in a
        )
