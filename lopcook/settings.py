"""Every knob lopcook has, with its unit, default and valid range: one frozen ``Settings``.

``Settings`` has one section per stage (``ingest``, ``simplify``, ``analyse``, ``viewing``,
``render``, ``tune``, ``attributes``, ``emit``); ``DEFAULTS`` is the instance with every default, and the CLI formats its
help texts from it. Choices are enums, never strings or tuples. ``Settings.to_manifest()`` gives
the container's ``options`` and ``viewing`` records and ``Settings.from_manifest()`` reads them
back (exactly: ``from_manifest(s.to_manifest()) == s`` for the recorded sections); a record that
does not parse is one ``LopcookError``, never a silent default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from enum import Enum
from fractions import Fraction

from .errors import LopcookError
from .grid import BITS
from .lop.codecs import CODECS
from .types import MAX_TRIANGLES
from .viewing import Viewing

__all__ = ["BITS", "DepthMode", "TextureSlope", "LodBackend", "SeamMode", "PsnrStat", "SearchKnobs", "BudgetScope",
           "LodSpec", "AttributeSettings", "IngestSettings", "SimplifySettings", "AnalyseSettings", "Viewing", "RenderSettings",
           "TuneSettings", "EmitSettings", "CLUSTER_SIZE_RANGE", "Settings", "DEFAULTS", "DEFAULT_INGEST", "DEFAULT_ANALYSE", "parse_resolution",
           "parse_lods", "budget_target"]


class DepthMode(str, Enum):
    """Depth constraints: ``AUTO`` from distances to other parts, ``OFF`` none, ``FIXED`` the
    paper's mode (vertices closer than ``depth_threshold`` metres to another part get
    ``depth_level``)."""

    AUTO = "auto"
    OFF = "off"
    FIXED = "fixed"


class TextureSlope(str, Enum):
    """Where the UVs' k_f comes from when it is not a number: ``IMAGE`` the base-colour texture's
    maximum slope, ``OFF`` UVs ignored."""

    IMAGE = "image"
    OFF = "off"


class LodBackend(str, Enum):
    """LOD simplifier (``lopcook.simplify.backends``)."""

    PYMESHLAB = "pymeshlab"
    FAST = "fast"
    MESHOPT = "meshopt"
    AUTO = "auto"


class SeamMode(str, Enum):
    """What the simplifier does with UV seams (``lopcook.simplify.chain``)."""

    LOCK = "lock"
    SIMPLIFY = "simplify"
    IGNORE = "ignore"
    XATLAS = "xatlas"
    AUTO = "auto"


class PsnrStat(str, Enum):
    """PSNR over views compared with a threshold: ``MIN`` every view, ``MEAN`` the PSNR of the
    view-averaged MSE."""

    MIN = "min"
    MEAN = "mean"


class SearchKnobs(str, Enum):
    """Knobs calibration searches: the k_f scale, or the k_f scale and the edge bound's eps."""

    KF = "kf"
    KF_EDGE = "kf+edge"


class BudgetScope(str, Enum):
    """What ``--target-bytes`` counts: the position buffer, + stored vertex attributes, + indices."""

    POSITIONS = "positions"
    VERTICES = "vertices"
    ALL = "all"


#: most LODs a default chain asks for (each half the triangles of the one before)
DEFAULT_LOD_LEVELS = 24


def halvings(max_levels: int = DEFAULT_LOD_LEVELS, triangles: int | None = None, min_triangles: int = 1) -> list[float]:
    """The default LOD chain: ratios 1/2, 1/4, 1/8, ... of LOD 0's triangles, at most
    ``max_levels`` of them, and, given ``triangles`` (LOD 0's count), only while
    ``round(ratio * triangles) >= min_triangles``. The one definition every default chain uses."""
    out, r = [], 0.5
    while len(out) < max_levels and (triangles is None or round(r * triangles) >= min_triangles):
        out.append(r)
        r /= 2.0
    return out


def _enum(kind, value, what: str):
    try:
        return kind(value)
    except ValueError:
        raise ValueError(f"{what} {value!r}: expected one of {', '.join(v.value for v in kind)}") from None


@dataclass(frozen=True)
class LodSpec:
    """The LOD chain asked for: ``auto`` (the default chain 1/2, 1/4, ... of ``max_levels``, cut
    where no view selects a LOD) or explicit fractions of LOD 0's triangles, in (0, 1),
    decreasing. ``text`` is the canonical spelling recorded in the manifest (``"auto"`` or
    ``"1/2,1/4"``)."""

    auto: bool = True
    ratios: tuple[float, ...] = ()
    max_levels: int = DEFAULT_LOD_LEVELS

    def __post_init__(self) -> None:
        r = self.ratios
        if not self.auto and (not r or any(not 0 < x < 1 for x in r) or any(a <= b for a, b in zip(r, r[1:]))):
            raise ValueError(f"LOD ratios {list(r)}: fractions must be in (0, 1) and decreasing")

    def resolved(self) -> list[float]:
        """The ratios to simplify to (the default chain for ``auto``)."""
        return halvings(self.max_levels) if self.auto else list(self.ratios)

    @property
    def text(self) -> str:
        if self.auto:
            return "auto"
        return ",".join(str(Fraction(x).limit_denominator(1 << 20)) for x in self.ratios)


def budget_target(text: str, float_size: int | None = None) -> int | None:
    """``--target-bytes``: an integer number of bytes, or P/Q of ``float_size`` (rounded down).
    With ``float_size`` None only the syntax is checked (returns None for a fraction)."""
    t = str(text).strip().replace("_", "").replace(",", "")
    try:
        value = Fraction(t)
    except (ValueError, ZeroDivisionError):
        raise LopcookError("usage", None, f"--target-bytes {text!r}: expected a number of bytes (e.g. 150000) "
                           "or a fraction of the float size (e.g. 1/6)") from None
    if "/" not in t:
        if value.denominator != 1 or value <= 0:
            raise LopcookError("usage", None, f"--target-bytes {text!r}: expected a positive whole number of bytes")
        return int(value)
    if not value > 0:
        raise LopcookError("usage", None, f"--target-bytes {text!r}: the fraction must be positive")
    return None if float_size is None else int(value * float_size)


def parse_lods(text: str | None) -> LodSpec | None:
    """``--lods`` text: ``"auto"`` or fractions such as ``"1/2,1/4"`` (a ratio of 1 is LOD 0 and
    dropped); None stays None (no LODs). Raises LopcookError("usage") on anything else."""
    if text is None:
        return None
    if text.strip().lower() == "auto":
        return LodSpec(auto=True)
    try:
        ratios = tuple(float(Fraction(t.strip())) for t in text.split(",") if t.strip())
    except (ValueError, ZeroDivisionError):
        raise LopcookError("usage", None, f"--lods {text!r}: expected auto or fractions such as 1/2,1/4,1/8") from None
    try:
        return LodSpec(auto=False, ratios=tuple(r for r in ratios if r != 1.0))
    except ValueError:
        raise LopcookError("usage", None, f"--lods {text!r}: fractions must be in (0, 1) and decreasing") from None


def parse_resolution(text: str, flag: str = "--resolution") -> tuple[int, int]:
    """``"WxH"`` -> (W, H) pixels, each in [1, 16384]; LopcookError("usage") otherwise."""
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise LopcookError("usage", None, f"{flag} {text!r}: expected WIDTHxHEIGHT, e.g. 1280x720") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise LopcookError("usage", None, f"{flag} {text!r}: width and height must be in [1, 16384] pixels")
    return w, h


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
    max_triangles : int in [1, ``lopcook.types.MAX_TRIANGLES``]
        Largest scene accepted, in triangles over all placements; importers count before they
        expand and refuse past it (exit 2). Default ``MAX_TRIANGLES`` (50 M).
    """

    crease_angle_deg: float = 60.0
    usd_time: str = "default"
    max_triangles: int = MAX_TRIANGLES

    def __post_init__(self) -> None:
        if not (0.0 <= self.crease_angle_deg <= 180.0):
            raise ValueError(f"crease_angle_deg must be in [0, 180], got {self.crease_angle_deg}")
        if isinstance(self.max_triangles, bool) or not 1 <= int(self.max_triangles) <= MAX_TRIANGLES:
            raise ValueError(f"max_triangles must be in [1, {MAX_TRIANGLES:,}], got {self.max_triangles}")


@dataclass(frozen=True)
class SimplifySettings:
    """Options of the simplify stage (LOD chains, ``lopcook.simplify``).

    lods : LodSpec or None  the chain to build; None = LOD 0 only (default)
    backend : LodBackend  the simplifier (default auto: meshoptimizer, and pymeshlab too on small
        inputs; chosen by measurement, docs/lod.md)
    seams : SeamMode  what happens to UV seams (default auto: collapsed along themselves, and the
        mesh welded by position where that stops short; docs/lod.md)
    hierarchy : bool  also write each part's view-dependent vertex hierarchy, built from LOD 0's
        full collapse sequence (``lopcook.hierarchy.container``; default False)
    instances : bool | None  store each group of copies of one mesh once, on a grid of its own, with
        one transform per placement (``lopcook.lop.placement``, docs/format.md). None (the default):
        wherever the scene has copies and the cook allows it (no hierarchy, no byte budget;
        ``lopcook.pipeline.resolve_instances``); True: always (a usage error with those); False: never
    """

    lods: LodSpec | None = None
    backend: LodBackend = LodBackend.AUTO
    seams: SeamMode = SeamMode.AUTO
    hierarchy: bool = False
    instances: bool | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "backend", _enum(LodBackend, self.backend, "LOD backend"))
        object.__setattr__(self, "seams", _enum(SeamMode, self.seams, "seam mode"))


@dataclass(frozen=True)
class AnalyseSettings:
    """Options of the analyse stage (minimum bit level per vertex).

    eps : float > 0, colour intensity; the largest shading error a vertex's quantization may cause
        (the CLI takes (0, 1]; calibration scales it). Default 1/255 (one 8-bit step).
    ks : float >= 0, dimensionless Phong specular coefficient. Default 0.5.
    shininess : float >= 0, dimensionless Phong specular exponent n. Default 32.
        The normal attribute's k_f = ks * shininess (colour per unit change of the normal).
    kf : float >= 0 or None: if given, overrides k_f for every attribute (colour per attribute unit).
    texture_kf : TextureSlope or float >= 0: k_f of UVs, ``IMAGE`` (the maximum slope of the
        base-colour texture in colour per UV unit, read from the image), ``OFF`` (UVs ignored) or
        a number (colour per UV unit). Parts without a texture use ``untextured_uv_kf``.
    untextured_uv_kf : float >= 0, colour per UV unit, for UVs of parts with no texture. Default 0
        (a UV set with no texture cannot change the colour).
    color_kf : float >= 0, colour per colour unit, for vertex colours. Default 1.
    depth : DepthMode; ``depth_level`` (int in [1, 24]) is the level of the paper's FIXED mode.
    depth_threshold : float >= 0, metres, for the paper's FIXED mode (must be > 0 there).
    depth_ceiling : int in [1, 24], the highest level a depth constraint may impose; vertices of
        touching/intersecting parts that would need more are capped there and reported. Default 16.
    edges : bool, the discontinuity constraint (``lopcook.analyse.discontinuity``): vertices on
        hard edges, folds sharper than a pixel, open boundaries and colour seams get
        ``m >= B_v + ceil(log2(0.5 * J / edge_eps))``. Default True (see docs/analyse.md).
    edge_eps : float, colour units in (0, 1]: the largest change of a pixel an edge of colour jump
        J may cause at per-buffer levels up to ``edge_level``. Default 1/8.
    edge_level : int in [1, 24], the highest per-buffer level the edge bound is kept at. Default 12.
    edge_angle_deg : float, degrees in (0, 180]: a one-pixel cell whose vertex normals spread by
        more than this holds a fold (a crease or a sub-pixel bevel). Default 45.
    position_margin : float in [1/4096, 4096], dimensionless: the E_v constraint of the positions
        (PRODUCT.md invariant 3) holds with ``position_eps = eps * position_margin``, i.e.
        ``k_f * E_v * dx(m_v) <= eps * position_margin``. Default 1, the paper's worst-case bound
        (docs/analyse.md, Position margin, has the measured margins). The attribute bits
        (``lopcook.analyse.attribute_bits.default_bits``) use ``eps`` itself.
    """

    eps: float = 1.0 / 255.0
    ks: float = 0.5
    shininess: float = 32.0
    kf: float | None = None
    texture_kf: TextureSlope | float = TextureSlope.IMAGE
    untextured_uv_kf: float = 0.0
    color_kf: float = 1.0
    depth: DepthMode = DepthMode.AUTO
    depth_level: int | None = None
    depth_threshold: float = 0.0
    depth_ceiling: int = 16
    edges: bool = True
    edge_eps: float = 0.125
    edge_level: int = 12
    edge_angle_deg: float = 45.0
    position_margin: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "depth", _enum(DepthMode, self.depth, "depth mode"))
        if not isinstance(self.texture_kf, TextureSlope):
            if isinstance(self.texture_kf, str):
                object.__setattr__(self, "texture_kf", _enum(TextureSlope, self.texture_kf, "texture k_f"))
            elif not (math.isfinite(float(self.texture_kf)) and float(self.texture_kf) >= 0):
                raise ValueError(f"texture_kf must be image, off or a finite number >= 0, got {self.texture_kf}")
        if not (math.isfinite(self.eps) and self.eps > 0):
            raise ValueError(f"eps must be a finite number > 0 (colour units), got {self.eps}")
        for name in ("ks", "shininess", "untextured_uv_kf", "color_kf", "depth_threshold"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")
        if self.kf is not None and not (math.isfinite(self.kf) and self.kf >= 0):
            raise ValueError(f"kf must be a finite number >= 0, got {self.kf}")
        if self.depth is DepthMode.FIXED:
            if self.depth_level is None or not 1 <= int(self.depth_level) <= BITS:
                raise ValueError(f"the fixed depth mode needs a level in [1, {BITS}], got {self.depth_level}")
            if not self.depth_threshold > 0:
                raise ValueError("the fixed depth mode needs a depth threshold > 0 metres")
        elif self.depth_level is not None:
            raise ValueError("depth_level is only used by the fixed depth mode")
        if not 1 <= int(self.depth_ceiling) <= BITS:
            raise ValueError(f"depth_ceiling must be in [1, 24], got {self.depth_ceiling}")
        if not (math.isfinite(self.edge_eps) and 0.0 < self.edge_eps <= 1.0):
            raise ValueError(f"edge_eps must be in (0, 1] (colour units), got {self.edge_eps}")
        if not 1 <= int(self.edge_level) <= BITS:
            raise ValueError(f"edge_level must be in [1, 24], got {self.edge_level}")
        if not (math.isfinite(self.edge_angle_deg) and 0.0 < self.edge_angle_deg <= 180.0):
            raise ValueError(f"edge_angle_deg must be in (0, 180] degrees, got {self.edge_angle_deg}")
        if not (math.isfinite(self.position_margin) and 2.0**-12 <= self.position_margin <= 2.0**12):
            raise ValueError(f"position_margin must be in [1/4096, 4096], got {self.position_margin}")

    @property
    def position_eps(self) -> float:
        """eps of the positions' E_v constraint, colour units: ``eps * position_margin``."""
        return float(self.eps) * float(self.position_margin)

    @property
    def normal_kf(self) -> float:
        """k_f for normals: ks * shininess unless ``kf`` overrides (colour per unit normal change)."""
        return float(self.kf) if self.kf is not None else self.ks * self.shininess

    @property
    def depth_text(self) -> str:
        """``"auto"``, ``"off"`` or ``"fixed:N"``: the CLI's and the manifest's spelling."""
        return f"fixed:{int(self.depth_level)}" if self.depth is DepthMode.FIXED else self.depth.value

    def to_record(self) -> dict:
        """The manifest's ``options.analyse`` record; ``position_margin`` only when it is not 1 (so
        a cook at the worst-case bound writes the same bytes as before the field existed)."""
        tk = self.texture_kf.value if isinstance(self.texture_kf, TextureSlope) else float(self.texture_kf)
        return {"eps": self.eps, "ks": self.ks, "shininess": self.shininess, "kf": self.kf, "texture_kf": tk,
                "untextured_uv_kf": self.untextured_uv_kf, "color_kf": self.color_kf, "depth": self.depth_text,
                "depth_threshold_m": self.depth_threshold, "depth_ceiling": self.depth_ceiling,
                "edges": bool(self.edges), "edge_eps": float(self.edge_eps), "edge_level": int(self.edge_level),
                "edge_angle_deg": float(self.edge_angle_deg),
                **({} if self.position_margin == 1.0 else {"position_margin": float(self.position_margin)})}

    @classmethod
    def from_record(cls, rec: dict) -> "AnalyseSettings":
        """Inverse of ``to_record``; ValueError/TypeError/KeyError on a record that does not parse."""
        kw = dict(rec)
        kw["depth_threshold"] = kw.pop("depth_threshold_m")
        kw.setdefault("position_margin", 1.0)  # files written before the field: the worst-case bound
        depth = str(kw.pop("depth"))
        if depth.startswith("fixed:"):
            kw["depth"], kw["depth_level"] = DepthMode.FIXED, int(depth.split(":", 1)[1])
        else:
            kw["depth"] = DepthMode(depth)
        known = {f.name for f in fields(cls)}
        unknown = set(kw) - known
        if unknown:
            raise ValueError(f"unknown analyse options {sorted(unknown)}")
        return cls(**kw)


@dataclass(frozen=True)
class RenderSettings:
    """The render harness (``lopcook.verify``): views in [1, 20] of the 20 icosahedron face-centre
    views, resolution (W, H) pixels, per-buffer levels in [1, 24], MSAA samples."""

    views: int = 20
    resolution: tuple[int, int] = (1280, 720)
    levels: tuple[int, ...] = tuple(range(6, 13))
    samples: int = 4

    def __post_init__(self) -> None:
        if not 1 <= int(self.views) <= 20:
            raise ValueError(f"views must be in [1, 20], got {self.views}")
        w, h = self.resolution
        if not (1 <= int(w) <= 16384 and 1 <= int(h) <= 16384):
            raise ValueError(f"resolution must be in [1, 16384] pixels, got {self.resolution}")
        if not self.levels or any(not 1 <= int(b) <= BITS for b in self.levels):
            raise ValueError(f"levels must be in [1, 24], got {self.levels}")

    @property
    def resolution_text(self) -> str:
        return f"{self.resolution[0]}x{self.resolution[1]}"


@dataclass(frozen=True)
class TuneSettings:
    """Searches above the stages (``lopcook.tune``).

    target_psnr : float dB or None  calibrate k_f to the least memory whose CAP renders reach it
    psnr_stat : PsnrStat  PSNR over views compared with the target
    search : SearchKnobs or None  knobs to search (None: k_f+edge when edges are on, else k_f)
    calibration : RenderSettings  the reduced harness every probe renders on when ``direct`` is off,
        and the attribute search's for a bit budget (``vertex_bits``)
    confirm : RenderSettings or None  the gate's harness (verify's): a direct search renders there and
        completes its choice at every level; otherwise the choice is confirmed there; None: neither
    direct : bool  ``target_psnr`` searches (k_f, then the attribute bits) render on ``confirm``'s
        views and resolution at the gate's levels 6..11, watching the levels where the default cook
        has the least margin (``lopcook.tune.calibrate``, "Watched levels"); off: on ``calibration``
    target_bytes : str or None  ``--target-bytes``: N bytes or P/Q of the float size
    budget_scope, budget : BudgetScope, RenderSettings  what the bytes count, the harness
    budget_levels : int >= 1  levels rendered per LOD by the budget fit
    vertex_bits : float or None  ``--vertex-bits``: the attribute search's bit budget per vertex at
        level 11 (``lopcook.tune.attributes``)
    attribute_search : bool  with ``target_psnr``, also search every attribute's bits (default on)
    """

    target_psnr: float | None = None
    psnr_stat: PsnrStat = PsnrStat.MIN
    search: SearchKnobs | None = None
    calibration: RenderSettings = RenderSettings(views=8, resolution=(640, 360))
    confirm: RenderSettings | None = RenderSettings()
    direct: bool = True
    target_bytes: str | None = None
    budget_scope: BudgetScope = BudgetScope.POSITIONS
    budget: RenderSettings = RenderSettings(views=20, resolution=(640, 360))
    budget_levels: int = 2
    vertex_bits: float | None = None
    attribute_search: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "psnr_stat", _enum(PsnrStat, self.psnr_stat, "PSNR statistic"))
        object.__setattr__(self, "budget_scope", _enum(BudgetScope, self.budget_scope, "budget scope"))
        if self.search is not None:
            object.__setattr__(self, "search", _enum(SearchKnobs, self.search, "search"))
        if self.target_psnr is not None and not (math.isfinite(self.target_psnr) and self.target_psnr > 0):
            raise ValueError(f"target PSNR must be a positive finite number of dB, got {self.target_psnr}")
        if int(self.budget_levels) < 1:
            raise ValueError(f"budget levels must be >= 1, got {self.budget_levels}")
        if self.vertex_bits is not None and not (math.isfinite(self.vertex_bits) and self.vertex_bits > 0):
            raise ValueError(f"vertex bits must be a positive finite number, got {self.vertex_bits}")


def _bits_tuple(values, what: str) -> tuple:
    """``values`` (a sequence in record order, shorter ones padded with None) checked against the
    codecs' ranges: a tuple of ``len(CODECS)`` ints or Nones; ValueError otherwise."""
    values = tuple(values)
    if len(values) > len(CODECS):
        raise ValueError(f"{what} must give at most {len(CODECS)} bits ({', '.join(c.singular for c in CODECS)}), "
                         f"got {values!r}")
    values = values + (None,) * (len(CODECS) - len(values))
    for c, v in zip(CODECS, values):
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or not c.bits[0] <= v <= c.bits[1]):
            raise ValueError(f"{c.singular} bits must be an integer in [{c.bits[0]}, {c.bits[1]}], got {v!r}")
    return values


@dataclass(frozen=True)
class AttributeSettings:
    """Bits per field of the packed vertex attributes, in the codecs' record order
    (``lopcook.lop.codecs.CODECS``: normals, uvs, colors, ...; each codec's ``bits`` range).

    bits : per codec, int or None; None is the bound-based default
        (``lopcook.analyse.attribute_bits.default_bits``). Shorter tuples are padded with None.
    parts : per scene part (in part order) bits in the same form, overriding ``bits`` for that
        part; empty: no per-part override. Used by the attribute search.
    ``AttributeSettings.of(normal=8, uv=12)`` names codecs by their singular (the CLI flags'
    ``--normal-bits``)."""

    bits: tuple = ()
    parts: tuple = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "bits", _bits_tuple(self.bits, "attribute bits"))
        object.__setattr__(self, "parts", tuple(_bits_tuple(p, "each per-part attribute entry") for p in self.parts))

    @classmethod
    def of(cls, parts=(), **by_singular) -> "AttributeSettings":
        known = {c.singular for c in CODECS}
        if set(by_singular) - known:
            raise ValueError(f"unknown attributes {sorted(set(by_singular) - known)} (known: {sorted(known)})")
        return cls(bits=tuple(by_singular.get(c.singular) for c in CODECS), parts=parts)

    def requested(self, part: int) -> dict:
        """``{codec name: bits or None}`` asked for part ``part`` (None: the bound-based default)."""
        own = (None,) * len(CODECS)
        if self.parts:
            if not 0 <= part < len(self.parts):
                raise ValueError(f"attribute bits are given for {len(self.parts)} parts, not for part {part}")
            own = self.parts[part]
        return {c.name: o if o is not None else b for c, o, b in zip(CODECS, own, self.bits)}

    @property
    def is_default(self) -> bool:
        return self == AttributeSettings()

    def _listed(self) -> int:
        """How many codecs the record lists: those of the first format, and later ones up to the
        last that any entry sets (so records without them keep their bytes)."""
        used = [i for i, c in enumerate(CODECS) if c.format_major > 2
                and any(row[i] is not None for row in (self.bits, *self.parts))]
        return max([sum(c.format_major == 2 for c in CODECS)] + [i + 1 for i in used])

    def to_record(self) -> dict:
        """The manifest's ``options.attributes`` record: ``<singular>_bits`` per listed codec and
        ``parts`` as lists in record order."""
        n = self._listed()
        rec = {f"{c.singular}_bits": b for c, b in zip(CODECS[:n], self.bits)}
        rec["parts"] = [list(p[:n]) for p in self.parts]
        return rec

    @classmethod
    def from_record(cls, rec: dict) -> "AttributeSettings":
        """Inverse of ``to_record``; ValueError/TypeError/KeyError on a record that does not parse."""
        base = {f"{c.singular}_bits" for c in CODECS if c.format_major == 2}
        allowed = {f"{c.singular}_bits" for c in CODECS} | {"parts"}
        if not isinstance(rec, dict) or not (base | {"parts"}) <= set(rec) <= allowed:
            raise ValueError(f"options.attributes must hold {', '.join(sorted(base))}, parts, got {rec!r}")
        listed = sum(f"{c.singular}_bits" in rec for c in CODECS)
        if not isinstance(rec["parts"], list) or not all(isinstance(p, list) and len(p) == listed for p in rec["parts"]):
            raise ValueError(f"options.attributes.parts must be a list of lists of {listed} bits in record order")
        return cls(bits=tuple(rec.get(f"{c.singular}_bits") for c in CODECS),
                   parts=tuple(tuple(p) for p in rec["parts"]))


CLUSTER_SIZE_RANGE = (16, 1024)
#: vertices per cluster of the default cook (docs/clusters.md: the best N, or within 0.1 point of
#: it, on every corpus asset and level measured)
DEFAULT_CLUSTER_SIZE = 64


@dataclass(frozen=True)
class EmitSettings:
    """Options of the emit stage (how position buffers are laid out).

    clusters : int in [16, 1024] or None  vertices per cluster of clustered position buffers
        (``lopcook.lop.clusters``: per-cluster anchors store the top bits a cluster's vertices
        share once; docs/clusters.md), default ``DEFAULT_CLUSTER_SIZE``; None: the unclustered
        binned layout (``cook --clusters 0``).
    cluster_all : bool  cluster every buffer (``cook --cluster-all``); default False: a buffer is
        clustered only when that makes it smaller (``lopcook.emit.clustering_wins``: GPU-resident
        bytes summed over levels 6-12), else written unclustered (docs/clusters.md, "Per-buffer
        choice").
    stream : bool  write the streaming layout with encoded sections (``cook --stream``, container
        version 4.0, ``lopcook.emit.stages.streamed``; docs/format.md 14-15); default False: the
        default layout, whose bytes do not change.
    """

    clusters: int | None = DEFAULT_CLUSTER_SIZE
    cluster_all: bool = False
    stream: bool = False

    def __post_init__(self) -> None:
        lo, hi = CLUSTER_SIZE_RANGE
        c = self.clusters
        if c is not None and (isinstance(c, bool) or not isinstance(c, int) or not lo <= c <= hi):
            raise ValueError(f"clusters must be an integer in [{lo}, {hi}] vertices per cluster, got {c!r}")


@dataclass(frozen=True)
class Settings:
    """Every section of a cook, frozen. ``Settings()`` is ``DEFAULTS``."""

    ingest: IngestSettings = field(default_factory=IngestSettings)
    simplify: SimplifySettings = field(default_factory=SimplifySettings)
    analyse: AnalyseSettings = field(default_factory=AnalyseSettings)
    viewing: Viewing = field(default_factory=Viewing)
    render: RenderSettings = field(default_factory=RenderSettings)
    tune: TuneSettings = field(default_factory=TuneSettings)
    attributes: AttributeSettings = field(default_factory=AttributeSettings)
    emit: EmitSettings = field(default_factory=EmitSettings)

    def with_(self, **sections) -> "Settings":
        """A copy with whole sections or fields of sections replaced: ``with_(analyse=...)`` or
        ``with_(analyse={"eps": 0.01})``."""
        kw = {}
        for name, value in sections.items():
            kw[name] = replace(getattr(self, name), **value) if isinstance(value, dict) else value
        return replace(self, **kw)

    def to_manifest(self) -> dict:
        """``{"options": ..., "viewing": ...}`` as the container records them (JSON types only).
        ``options.lods`` is present only when a LOD chain is asked for, ``options.hierarchy``
        (true) only with ``simplify.hierarchy``, ``options.instances`` only when ``simplify.instances``
        is given (true or false; the default, None, writes none, and ``lopcook.pipeline.run`` adds
        true where the default stored copies once), ``options.attributes`` only when attribute bits
        are asked for: default containers keep their options record."""
        options = {"analyse": self.analyse.to_record(), "ingest": {"crease_angle_deg": self.ingest.crease_angle_deg}}
        if self.simplify.lods is not None:
            options["lods"] = {"ratios": self.simplify.lods.text, "backend": self.simplify.backend.value,
                               "seams": self.simplify.seams.value}
        if self.simplify.hierarchy:
            options["hierarchy"] = True
        if self.simplify.instances is not None:
            options["instances"] = bool(self.simplify.instances)
        if not self.attributes.is_default:
            options["attributes"] = self.attributes.to_record()
        if self.emit.clusters is not None:
            options["clusters"] = int(self.emit.clusters)
            if self.emit.cluster_all:
                options["cluster_all"] = True
        if self.emit.stream:
            options["stream"] = True
        return {"options": options, "viewing": self.viewing.as_dict()}

    @classmethod
    def from_manifest(cls, manifest: dict, path: str | None = None) -> "Settings":
        """The settings a container was cooked with (its ``options`` and ``viewing`` records;
        render and tune sections at their defaults). Raises LopcookError("container") when a record
        is missing or does not parse."""
        try:
            options = manifest["options"]
            analyse = AnalyseSettings.from_record(options["analyse"])
            ingest = IngestSettings(crease_angle_deg=float(options["ingest"]["crease_angle_deg"]))
            simplify = SimplifySettings()
            if options.get("lods") is not None:
                lods = options["lods"]
                # containers written before options.lods.seams were cooked with locked seams
                simplify = SimplifySettings(lods=parse_lods(str(lods["ratios"])), backend=LodBackend(lods["backend"]),
                                            seams=SeamMode(lods.get("seams", "lock")))
            if options.get("hierarchy", False) is not False:
                if options["hierarchy"] is not True:
                    raise ValueError(f"options.hierarchy must be true when present, got {options['hierarchy']!r}")
                simplify = replace(simplify, hierarchy=True)
            # absent: the default (copies stored once wherever the scene has them, and then recorded
            # true; containers of an older lopcook without the record kept copies apart)
            instances = options.get("instances")
            if instances is not None and instances is not False and instances is not True:
                raise ValueError(f"options.instances must be true or false when present, got {instances!r}")
            simplify = replace(simplify, instances=instances)
            attributes = AttributeSettings()
            if options.get("attributes") is not None:
                attributes = AttributeSettings.from_record(options["attributes"])
            # no options.clusters: cooked unclustered (before clusters were the default, or --clusters 0)
            emit = EmitSettings(clusters=None)
            if options.get("clusters") is not None:
                if options.get("cluster_all", False) not in (False, True):
                    raise ValueError(f"options.cluster_all must be true when present, got {options['cluster_all']!r}")
                emit = EmitSettings(clusters=options["clusters"], cluster_all=options.get("cluster_all", False))
            if options.get("stream", False) not in (False, True):
                raise ValueError(f"options.stream must be true when present, got {options['stream']!r}")
            emit = replace(emit, stream=bool(options.get("stream", False)))
            v = manifest["viewing"]
            viewing = Viewing(viewport=(int(v["viewport"][0]), int(v["viewport"][1])),
                              fov_y_deg=float(v["fov_y_deg"]),
                              nearest_m=None if v["nearest_m"] is None else float(v["nearest_m"]),
                              pixel_error=float(v["pixel_error"]))
        except (KeyError, TypeError, ValueError, IndexError, LopcookError) as exc:
            what = exc.message if isinstance(exc, LopcookError) else (
                f"missing {exc}" if isinstance(exc, KeyError) else str(exc))
            raise LopcookError("container", path, f"the recorded cook options do not parse ({what})",
                               hint="cook the source again with this lopcook version") from None
        return cls(ingest=ingest, simplify=simplify, analyse=analyse, viewing=viewing, attributes=attributes,
                   emit=emit)


DEFAULTS = Settings()
DEFAULT_INGEST = DEFAULTS.ingest
DEFAULT_ANALYSE = DEFAULTS.analyse
