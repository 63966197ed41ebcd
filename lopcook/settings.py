"""Every knob lopcook has, with its unit, default and valid range (one place, as data)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class IngestSettings:
    """Options of the ingest stage.

    crease_angle_deg : float, degrees, in [0, 180]
        When a source has no normals, lopcook computes them. Faces meeting at an edge whose
        dihedral angle exceeds this are shaded apart (the vertex is split along the crease);
        180 gives fully smooth normals, 0 gives flat shading. Default 60.
    usd_time : str
        Time code USD attributes are read at: ``"default"`` (Usd.TimeCode.Default(), falling back
        to the earliest time sample when no default is authored) or a number.
    """

    crease_angle_deg: float = 60.0
    usd_time: str = "default"

    def __post_init__(self) -> None:
        if not (0.0 <= self.crease_angle_deg <= 180.0):
            raise ValueError(f"crease_angle_deg must be in [0, 180], got {self.crease_angle_deg}")


DEFAULT_INGEST = IngestSettings()
