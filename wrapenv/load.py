"""The load unit: pallet, bundles, stacking pattern, contact friction and fixtures.

A `LoadUnit` is what a LOAD.toml describes. `LoadUnit.layout()` turns it into the boxes the
bench simulates (`Layout`), laid out in the sled frame: x along the motion, z up, the underside
of the pallet at z = 0 and the pallet centred on x = y = 0.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, cast

import tomli_w

from wrapenv.config import (
    MAX_FRICTION_COEFFICIENT,
    InputError,
    Table,
    is_finite_number,
    read_toml,
)
from wrapenv.load_checks import (
    BUNDLE_GAP_M,
    MAX_LOAD_HEIGHT_M,
    check_unit,
    fit,
    footprints_overlap,
)

Pattern = Literal["columnar", "interlocked", "explicit"]
#: Which of the pallet's sides lies along the sled's motion.
Orientation = Literal["long", "short"]
ORIENTATIONS: tuple[Orientation, ...] = ("long", "short")
PATTERNS: tuple[str, ...] = ("columnar", "interlocked", "explicit")
PAIRS: tuple[str, ...] = ("sled_pallet", "pallet_bundle", "bundle_bundle")


#: The EPAL Euro pallet's safe working load, evenly spread [S] (docs/materials.md, U0): what a
#: pallet described by its size alone is taken to carry.
EUR_SAFE_LOAD_KG = 1500.0


@dataclass(frozen=True)
class Pallet:
    length_m: float
    width_m: float
    height_m: float
    mass_kg: float
    #: The most the pallet carries, evenly spread (its safe working load): a heavier stack
    #: is a unit no pallet of this kind carries, refused when the load file is read.
    safe_load_kg: float = EUR_SAFE_LOAD_KG


#: The give of a shrink-wrapped PET bundle's vertical edge under the wrap [A]: 1.7 mm of dent
#: under 100 N spread over 0.1 m of edge (docs/materials.md, section 5, B1).
PET_CORNER_STIFFNESS_N_PER_M2 = 6.0e5
#: Its edge is the corner bottle's side: half of a 1.5 L bottle's ~90 mm diameter [D] (B2).
PET_EDGE_RADIUS_M = 0.045
#: Give a load file accepts, N/m per m of edge: softer is a pillow, stiffer a steel post. A
#: calibration may scale it beyond (CAL.json's give_scale); a run that does not stay physical
#: is invalid, never a pass.
CORNER_STIFFNESS_RANGE_N_PER_M2 = (1.0e4, 5.0e6)


@dataclass(frozen=True)
class Bundle:
    """One bundle: its box, and how its vertical edges take the wrap (the load's give)."""

    length_m: float
    width_m: float
    height_m: float
    mass_kg: float
    #: Force per metre of dent per metre of edge height where the wrap presses on a vertical
    #: edge: the load-side compliance in series with the web.
    corner_stiffness_n_per_m2: float = PET_CORNER_STIFFNESS_N_PER_M2
    #: Radius of the vertical edges the web turns round: a bottle's side is round, a carton's
    #: folded edge sharp (a few mm); the web bends round it, which concentrates its strain.
    edge_radius_m: float = PET_EDGE_RADIUS_M


#: EPAL's pallets (length x width x height, mass, safe working load; docs/materials.md, U3):
#: the Euro pallet (EPAL 1, EN 13698-1), the 1200 x 1000 mm industrial pallets (EPAL 2 with
#: its base frame, EPAL 3) and the half pallet (EPAL 6) the drinks trade ships on, whose
#: height and mass are assumed [A]: its sources give neither exactly.
PALLET_PRESETS = {
    "EUR": Pallet(1.200, 0.800, 0.144, 25.0, EUR_SAFE_LOAD_KG),
    "EPAL2": Pallet(1.200, 1.000, 0.162, 35.0, 1250.0),
    "EPAL3": Pallet(1.000, 1.200, 0.144, 30.0, 1500.0),
    "EPAL6": Pallet(0.800, 0.600, 0.144, 9.5, 500.0),
}
#: The most a load file may say its pallet carries [A]: the highest rating the sources give a
#: wooden pallet in transport, the Euro pallet's with a compact load spread evenly over the
#: whole deck (docs/materials.md, U0); a larger figure is a typo, not a pallet.
MAX_SAFE_LOAD_KG = 2000.0
#: What a friction figure above MAX_FRICTION_COEFFICIENT most likely is.
COEFFICIENT_HINT = ("a coefficient (the tangent of the slide angle: 0.45 for 24°), not a "
                    "percentage or an angle")
#: The largest a pallet's or a bundle's box can be: no side beyond the tallest unit a trailer
#: takes, no mass beyond what the strongest pallet carries. Beyond them a figure is a unit slip
#: (millimetres, grams), which the error then names.
BOX_LIMITS = {"length_m": MAX_LOAD_HEIGHT_M, "width_m": MAX_LOAD_HEIGHT_M,
              "height_m": MAX_LOAD_HEIGHT_M, "mass_kg": MAX_SAFE_LOAD_KG}
#: Six 1.5 L PET bottles in shrink film, 3 x 2 bottles of ~90 mm diameter and ~330 mm height:
#: 6 x (1.5 kg water + ~50 g PET and cap); give as above.
BUNDLE_PRESETS = {"PET6x1.5L": Bundle(0.28, 0.19, 0.33, 9.3, PET_CORNER_STIFFNESS_N_PER_M2,
                                      PET_EDGE_RADIUS_M)}


@dataclass(frozen=True)
class FrictionPair:
    """Coulomb friction of one contact pair: sticking up to `static`, sliding at `kinetic`."""

    static: float
    kinetic: float


#: The kinetic share of a static coefficient the CTU Code advises where only the static one is
#: known (the defaults below follow it).
KINETIC_SHARE = 0.75


@dataclass(frozen=True)
class Friction:
    """Per contact pair coefficients. Defaults (static from the CTU Code, appendix 2, and
    EN 12195-1; kinetic = 0.75 x static as the CTU Code advises):
    wooden pallet on a plywood sled deck 0.45, wooden pallet on shrink film 0.30, shrink film
    on shrink film 0.30."""

    sled_pallet: FrictionPair = FrictionPair(0.45, 0.34)
    pallet_bundle: FrictionPair = FrictionPair(0.30, 0.23)
    bundle_bundle: FrictionPair = FrictionPair(0.30, 0.23)

    def pair(self, name: str) -> FrictionPair:
        return getattr(self, name)


@dataclass(frozen=True)
class Stack:
    layers: int
    pattern: Pattern = "columnar"
    #: Bundle centres (x, y) from the pallet centre, used by the "explicit" pattern.
    positions: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class BundlePlacement:
    """One bundle box as simulated: its name, layer (1 = bottom) and centre in the sled frame."""

    name: str
    layer: int
    centre_m: tuple[float, float, float]
    size_m: tuple[float, float, float]
    mass_kg: float
    corner_stiffness_n_per_m2: float = PET_CORNER_STIFFNESS_N_PER_M2  # see `Bundle`
    edge_radius_m: float = PET_EDGE_RADIUS_M


@dataclass(frozen=True)
class Layout:
    """Boxes of a load unit placed in the sled frame, ready to simulate."""

    pallet_size_m: tuple[float, float, float]
    pallet_mass_kg: float
    bundles: tuple[BundlePlacement, ...]
    friction: Friction
    pallet_stopper: bool

    @property
    def load_height_m(self) -> float:
        return max(b.centre_m[2] + b.size_m[2] / 2 for b in self.bundles)

    @property
    def outline_m(self) -> tuple[float, float]:
        """Extent (x, y) of the bundles seen from above: the outline a wrap goes round."""
        xs = [b.centre_m[0] + s * b.size_m[0] / 2 for b in self.bundles for s in (-1, 1)]
        ys = [b.centre_m[1] + s * b.size_m[1] / 2 for b in self.bundles for s in (-1, 1)]
        return max(xs) - min(xs), max(ys) - min(ys)

    def supports(self) -> list[list[int]]:
        """For each bundle, the indices of the bundles it rests on (empty: on the pallet)."""
        out = []
        for b in self.bundles:
            below = [
                j
                for j, o in enumerate(self.bundles)
                if o.layer == b.layer - 1 and footprints_overlap(b, o)
            ]
            out.append(below)
        return out


#: The bundled example, the unit the environments and `recommend` take when given none: a
#: link to examples/pet_2layer_columnar.toml inside the package, copied into wheels.
EXAMPLE_LOAD = Path(__file__).resolve().parent / "data" / "example_load.toml"


@dataclass(frozen=True)
class LoadUnit:
    """LOAD.toml (CONTRACTS.md): the pallet, the bundle, how they are stacked, friction per
    contact pair and the bench's stop bar, checked once in `from_dict`; `layout` places the
    boxes the bench simulates."""

    name: str
    pallet: Pallet
    bundle: Bundle
    stack: Stack
    friction: Friction = field(default_factory=Friction)
    pallet_stopper: bool = False

    @property
    def load_height_m(self) -> float:
        """Height of the unit above the sled: pallet plus every layer."""
        return self.pallet.height_m + self.stack.layers * self.bundle.height_m

    @property
    def mass_kg(self) -> float:
        return self.pallet.mass_kg + self.bundle.mass_kg * len(self.layout().bundles)

    def with_friction(self, friction: Friction) -> LoadUnit:
        return replace(self, friction=friction)

    def with_give(self, scale: float) -> LoadUnit:
        """The unit with its bundles' edges `scale` times as stiff under the wrap: how a
        calibration or a robust search varies the load's give."""
        stiffness = self.bundle.corner_stiffness_n_per_m2 * scale
        return replace(self, bundle=replace(self.bundle, corner_stiffness_n_per_m2=stiffness))

    def layout(self, orientation: Orientation | None = None) -> Layout:
        """Place the bundles. ``orientation`` puts the pallet's long or short side along the
        motion (x); None keeps the file's layout (pallet length along x)."""
        p = self.pallet
        turn = (orientation == "long" and p.length_m < p.width_m) or (
            orientation == "short" and p.length_m > p.width_m
        )
        bundles = []
        for layer, (turned, xy_list) in enumerate(_pattern_layers(self), start=1):
            z = p.height_m + (layer - 0.5) * self.bundle.height_m
            size = (self.bundle.length_m, self.bundle.width_m, self.bundle.height_m)
            if turned != turn:
                size = (size[1], size[0], size[2])
            if turn:
                xy_list = [(-y, x) for x, y in xy_list]
            for name, (x, y) in _names(layer, xy_list):
                bundles.append(BundlePlacement(name, layer, (x, y, z), size, self.bundle.mass_kg,
                                               self.bundle.corner_stiffness_n_per_m2,
                                               self.bundle.edge_radius_m))
        pallet_size = (p.width_m, p.length_m, p.height_m) if turn else (
            p.length_m, p.width_m, p.height_m)
        bundles.sort(key=lambda b: (b.layer, b.centre_m[0], b.centre_m[1]))
        return Layout(pallet_size, p.mass_kg, tuple(bundles), self.friction, self.pallet_stopper)

    def to_dict(self) -> dict:
        """The LOAD.toml content with every value written out (no presets), so the file says
        exactly what was simulated; `from_dict` reads it back equal."""
        stack: dict = {"layers": self.stack.layers, "pattern": self.stack.pattern}
        if self.stack.pattern == "explicit":
            stack["positions"] = [list(p) for p in self.stack.positions]
        return {
            "name": self.name,
            "pallet": asdict(self.pallet),
            "bundle": asdict(self.bundle),
            "stack": stack,
            "friction": {name: asdict(self.friction.pair(name)) for name in PAIRS},
            "fixture": {"pallet_stopper": self.pallet_stopper},
        }

    def to_toml(self) -> str:
        """The LOAD.toml text, written by a TOML library (every name reads back equal)."""
        return "# Load unit (LOAD.toml); metres, kilograms.\n" + tomli_w.dumps(self.to_dict())

    @classmethod
    def from_toml(cls, path: str | Path) -> LoadUnit:
        return cls.from_dict(read_toml(path), source=str(path))

    @classmethod
    def from_dict(cls, data: dict, source: str = "load") -> LoadUnit:
        top = Table(data, source)
        name = top.string("name", "load unit")
        pallet = _pallet(top.table("pallet", required=True))
        bundle = _bundle(top.table("bundle", required=True))
        stack = _stack(top.table("stack", required=True))
        friction = _friction(top.table("friction"))
        fixture = top.table("fixture")
        stopper = fixture.boolean("pallet_stopper", False)
        fixture.done()
        top.done()
        unit = cls(name, pallet, bundle, stack, friction, stopper)
        check_unit(unit, source)
        return unit


def _sized(t: Table, kind: type, presets: dict) -> Any:
    """A pallet or bundle box: a preset's values, or those given, keys overriding the preset;
    the table is left open for the keys that follow (the pallet's rating, the bundle's give)."""
    base = None
    if t.has("preset"):
        key = t.choice("preset", presets)
        base = presets[key]
    values = {}
    for key in ("length_m", "width_m", "height_m", "mass_kg"):
        default = getattr(base, key) if base is not None else None
        values[key] = t.number(key, default, positive=True, maximum=BOX_LIMITS[key])
    return kind(**values) if base is None else replace(base, **values)


def _pallet(t: Table) -> Pallet:
    """The pallet's box, then what it carries: a preset's rating, or the Euro pallet's."""
    box: Pallet = _sized(t, Pallet, PALLET_PRESETS)
    safe_load = t.number("safe_load_kg", box.safe_load_kg, positive=True,
                         maximum=MAX_SAFE_LOAD_KG)
    t.done()
    return replace(box, safe_load_kg=safe_load)


def _bundle(t: Table) -> Bundle:
    """The bundle's box, then its give: optional keys, a preset's values or the documented
    defaults (a shrink-wrapped PET bundle's), and an edge no rounder than the bundle allows."""
    box: Bundle = _sized(t, Bundle, BUNDLE_PRESETS)
    low, high = CORNER_STIFFNESS_RANGE_N_PER_M2
    stiffness = t.number("corner_stiffness_n_per_m2", box.corner_stiffness_n_per_m2,
                         minimum=low, maximum=high)
    roundest = min(box.length_m, box.width_m) / 2
    radius = t.number("edge_radius_m", min(box.edge_radius_m, roundest), positive=True)
    if radius > roundest:
        raise t.error("edge_radius_m", f"must be <= half the bundle's smaller side "
                      f"({roundest} m) (got {radius})")
    t.done()
    return replace(box, corner_stiffness_n_per_m2=stiffness, edge_radius_m=radius)


def _stack(t: Table) -> Stack:
    layers = t.integer("layers", minimum=1)
    pattern = t.choice("pattern", PATTERNS, "columnar")
    positions: tuple[tuple[float, float], ...] = ()
    if pattern == "explicit":
        raw = t.array("positions")
        if not raw:
            raise t.error("positions", "must list at least one bundle centre")
        parsed: list[tuple[float, float]] = []
        for i, item in enumerate(raw):
            ok = isinstance(item, list) and len(item) == 2 and all(map(is_finite_number, item))
            if not ok:
                raise t.error(f"positions[{i}]", f"must be [x, y] in metres (got {item!r})")
            point = (float(item[0]), float(item[1]))
            if point in parsed:
                raise t.error(f"positions[{i}]", f"is positions[{parsed.index(point)}] again "
                                                 f"({item!r}): two bundles in one place")
            parsed.append(point)
        positions = tuple(parsed)
    t.done()
    return Stack(layers, cast(Pattern, pattern), positions)


def _friction(t: Table) -> Friction:
    pairs = {}
    for name in PAIRS:
        if not t.has(name):
            continue
        if is_finite_number(t.data[name]):
            raise t.error(name, f"must be a table {{ static = ..., kinetic = ... }} (got "
                          f"{t.data[name]!r}: a single coefficient is a static one; "
                          f"{_kinetic_advice(float(t.data[name]))})")
        p = t.table(name)
        static = p.number("static", positive=True, maximum=MAX_FRICTION_COEFFICIENT,
                          hint=COEFFICIENT_HINT)
        if not p.has("kinetic"):
            raise p.error("kinetic", f"missing ({_kinetic_advice(static)})")
        kinetic = p.number("kinetic", positive=True, maximum=MAX_FRICTION_COEFFICIENT,
                           hint=COEFFICIENT_HINT)
        p.done()
        if kinetic > static:
            raise InputError(t.source, p.field("kinetic"),
                             f"kinetic friction {kinetic} exceeds static {static}")
        pairs[name] = FrictionPair(static, kinetic)
    t.done()
    return replace(Friction(), **pairs)


def _kinetic_advice(static: float) -> str:
    """What to give as the kinetic coefficient when only the static one is known."""
    return (f"where only the static coefficient is known, the CTU Code advises kinetic = "
            f"{KINETIC_SHARE} x static: kinetic = {KINETIC_SHARE * static:.2f}")


def _grid(length: float, size: float) -> list[float]:
    """Centres of as many boxes of `size` as fit in `length`, centred, `BUNDLE_GAP_M` apart."""
    n = fit(length, size)
    pitch = size + BUNDLE_GAP_M
    return [(i - (n - 1) / 2) * pitch for i in range(n)]


def _pattern_layers(unit: LoadUnit) -> list[tuple[bool, list[tuple[float, float]]]]:
    """Per layer: whether its bundles are turned 90 degrees, and their centres (x, y)."""
    p, b, s = unit.pallet, unit.bundle, unit.stack
    if s.pattern == "explicit":
        return [(False, list(s.positions)) for _ in range(s.layers)]
    straight = [(x, y) for x in _grid(p.length_m, b.length_m) for y in _grid(p.width_m, b.width_m)]
    if s.pattern == "columnar":
        return [(False, straight) for _ in range(s.layers)]
    # Interlocked: every second layer is turned 90 degrees, so each of its bundles rests across
    # the joints of the layer below and ties neighbouring columns together.
    turned = [(x, y) for x in _grid(p.length_m, b.width_m) for y in _grid(p.width_m, b.length_m)]
    return [(layer % 2 == 1, turned if layer % 2 == 1 else straight) for layer in range(s.layers)]


def _names(layer: int, xy: list[tuple[float, float]]) -> list[tuple[str, tuple[float, float]]]:
    cols = sorted({round(x, 4) for x, _ in xy})
    rows = sorted({round(y, 4) for _, y in xy})
    return [
        (f"L{layer}C{cols.index(round(x, 4)) + 1}R{rows.index(round(y, 4)) + 1}", (x, y))
        for x, y in xy
    ]
