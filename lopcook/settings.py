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


@dataclass(frozen=True)
class AnalyseSettings:
    """Options of the analyse stage (minimum bit level per vertex).

    eps : float, colour intensity in [0, 1] units; the largest shading error a vertex's
        quantization may cause. Default 1/255 (one 8-bit step).
    ks : float, dimensionless Phong specular coefficient. Default 0.5.
    shininess : float, dimensionless Phong specular exponent n. Default 32.
        The normal attribute's k_f = ks * shininess (colour per unit change of the normal).
    kf : float or None: if given, overrides k_f for every attribute (colour per attribute unit).
    texture_kf : "image" (k_f of UVs = the maximum slope of the base-colour texture, in colour
        per UV unit, read from the image), a float (colour per UV unit), or "off" (UVs ignored).
        Parts without a texture use ``untextured_uv_kf``.
    untextured_uv_kf : float, colour per UV unit, for UVs of parts with no texture. Default 0
        (a UV set with no texture cannot change the colour).
    color_kf : float, colour per colour unit, for vertex colours. Default 1.
    depth : "auto" (depth levels from the distance to other parts), "off", or ("fixed", N) for
        the paper's mode: vertices closer than ``depth_threshold`` metres to another part get N.
    depth_threshold : float, metres, for the paper's fixed mode.
    depth_ceiling : int in [1, 24], the highest level a depth constraint may impose; vertices of
        touching/intersecting parts that would need more are capped there and reported. Default 16.
    edges : bool, the discontinuity constraint (``lopcook.analyse.discontinuity``): vertices on
        hard edges, folds sharper than a pixel, open boundaries and colour seams get
        ``m >= B_v + ceil(log2(0.5 * J / edge_eps))``. Default True (without it, flat-shaded CAD
        and hard-surface assets cannot reach 40 dB at any k_f; see docs/analyse.md).
    edge_eps : float, colour units in (0, 1]: the largest change of a pixel an edge of colour jump
        J may cause at per-buffer levels up to ``edge_level``. Default 1/8 (a jump of 1 costs
        B_v + 2 bits). ``lopcook calibrate`` can search it.
    edge_level : int in [1, 24], the highest per-buffer level the edge bound is kept at (the
        render harness's default levels are 6..12). Default 12.
    edge_angle_deg : float, degrees in (0, 180]: a one-pixel cell whose vertex normals spread by
        more than this holds a fold (a crease or a sub-pixel bevel). Default 45.
    """

    eps: float = 1.0 / 255.0
    ks: float = 0.5
    shininess: float = 32.0
    kf: float | None = None
    texture_kf: object = "image"
    untextured_uv_kf: float = 0.0
    color_kf: float = 1.0
    depth: object = "auto"
    depth_threshold: float = 0.0
    depth_ceiling: int = 16
    edges: bool = True
    edge_eps: float = 0.125
    edge_level: int = 12
    edge_angle_deg: float = 45.0

    def __post_init__(self) -> None:
        if not self.eps > 0:
            raise ValueError(f"eps must be > 0 (colour units), got {self.eps}")
        for name in ("ks", "shininess", "untextured_uv_kf", "color_kf"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.kf is not None and not self.kf >= 0:
            raise ValueError(f"kf must be >= 0, got {self.kf}")
        if not 1 <= int(self.depth_ceiling) <= 24:
            raise ValueError(f"depth_ceiling must be in [1, 24], got {self.depth_ceiling}")
        if not 0.0 < self.edge_eps <= 1.0:
            raise ValueError(f"edge_eps must be in (0, 1] (colour units), got {self.edge_eps}")
        if not 1 <= int(self.edge_level) <= 24:
            raise ValueError(f"edge_level must be in [1, 24], got {self.edge_level}")
        if not 0.0 < self.edge_angle_deg <= 180.0:
            raise ValueError(f"edge_angle_deg must be in (0, 180] degrees, got {self.edge_angle_deg}")

    @property
    def normal_kf(self) -> float:
        """k_f for normals: ks * shininess unless ``kf`` overrides (colour per unit normal change)."""
        return float(self.kf) if self.kf is not None else self.ks * self.shininess


DEFAULT_ANALYSE = AnalyseSettings()
