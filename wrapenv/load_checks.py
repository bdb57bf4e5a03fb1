"""What a load unit may be: limits a pallet and the bench set (docs/materials.md, section 6),
and layouts no bench could hold (bundles over the edge, overlapping, or over nothing).

`check_unit` runs when a LOAD.toml is read (`wrapenv.load.LoadUnit.from_dict`); the limits are
checked by arithmetic first, so a unit of a million bundles is refused before any is placed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from wrapenv.config import InputError

if TYPE_CHECKING:
    from wrapenv.load import BundlePlacement, LoadUnit

#: Gap left between neighbouring bundles of a generated pattern, so no two boxes start in contact
#: sideways (real bundles are stacked touching; 2 mm is below what the EUMOS criteria resolve).
BUNDLE_GAP_M = 0.002
#: Largest overhang tolerated when checking that bundles stay on the pallet (rounding of layouts).
OVERHANG_TOLERANCE_M = 0.001
#: The height of a loaded pallet a road trailer takes (docs/materials.md, section 6,
#: "Load-unit limits"; what a pallet carries is its own, `Pallet.safe_load_kg`): European
#: trailers are 2.55 to 3.00 m high inside [S]; a taller unit travels in no truck.
MAX_LOAD_HEIGHT_M = 3.0
#: A bundle's smallest side [A]: below 5 cm a box is no bundle of goods, and the bench's
#: contact tolerances (its 20 mm interpenetration limit) would be a large part of it.
MIN_BUNDLE_SIDE_M = 0.05
#: A bundle's least mass per volume [A]: the lightest goods shipped on pallets (packs of empty
#: PET bottles, about 10 kg/m³; expanded polystyrene, 15) weigh more. Lighter is a unit slip
#: (grams, a tonne given as kg), and the bench's contact solve cannot hold such boxes under a
#: wrap (docs/bench.md, "What it cannot hold").
MIN_BUNDLE_DENSITY_KG_M3 = 5.0
#: Most bundles the bench simulates [A]: one rigid body each, stepped 240 times a second;
#: a level's time grows with their number (docs/materials.md, section 6).
MAX_BUNDLES = 500


def fit(length: float, size: float) -> int:
    """How many boxes of `size` fit in `length`, `BUNDLE_GAP_M` apart."""
    return int((length + BUNDLE_GAP_M) // (size + BUNDLE_GAP_M))


def _bundle_count(unit: LoadUnit) -> int:
    """How many bundles the stack holds, counted without placing them (the patterns of
    `LoadUnit.layout`: interlocked layers alternate straight and turned, straight first)."""
    p, b, s = unit.pallet, unit.bundle, unit.stack
    if s.pattern == "explicit":
        return len(s.positions) * s.layers
    straight = fit(p.length_m, b.length_m) * fit(p.width_m, b.width_m)
    if s.pattern == "columnar":
        return straight * s.layers
    turned = fit(p.length_m, b.width_m) * fit(p.width_m, b.length_m)
    return straight * ((s.layers + 1) // 2) + turned * (s.layers // 2)


def _check_limits(unit: LoadUnit, source: str) -> None:
    """Reject units no pallet carries or no bench could simulate, before any is laid out:
    bundles too small to be goods, taller than a truck takes, more bundles than the bench
    simulates, heavier than the pallet's safe working load (docs/materials.md, section 6)."""
    b = unit.bundle
    for key in ("length_m", "width_m", "height_m"):
        if getattr(b, key) < MIN_BUNDLE_SIDE_M:
            raise InputError(source, f"bundle.{key}",
                             f"must be >= {MIN_BUNDLE_SIDE_M} m, the smallest bundle the bench"
                             f" takes (got {getattr(b, key)})")
    density = b.mass_kg / (b.length_m * b.width_m * b.height_m)
    if density < MIN_BUNDLE_DENSITY_KG_M3:
        raise InputError(source, "bundle.mass_kg",
                         f"{b.mass_kg} kg in a {1000 * b.length_m * b.width_m * b.height_m:.1f}"
                         f" L box is {density:.2g} kg/m³, lighter than any goods (packs of empty"
                         f" bottles: about 10 kg/m³; at least {MIN_BUNDLE_DENSITY_KG_M3:g})")
    height = unit.load_height_m
    if height > MAX_LOAD_HEIGHT_M:
        # the field to change: the layers, unless one layer alone is too tall
        field = "stack.layers" if unit.stack.layers > 1 else (
            "pallet.height_m" if unit.pallet.height_m > unit.bundle.height_m
            else "bundle.height_m")
        raise InputError(source, field,
                         f"{unit.stack.layers} layers make the unit {height:.2f} m tall, above"
                         f" the {MAX_LOAD_HEIGHT_M} m a road trailer takes inside (European"
                         f" trailers: 2.55-3.00 m)")
    count = _bundle_count(unit)
    if count > MAX_BUNDLES:
        raise InputError(source, "stack.layers",
                         f"the stack holds {count} bundles, more than the {MAX_BUNDLES} the"
                         f" bench simulates")
    payload, safe_load = count * b.mass_kg, unit.pallet.safe_load_kg
    if payload > safe_load:
        raise InputError(source, "bundle.mass_kg",
                         f"{count} bundles of {b.mass_kg} kg weigh {payload:.0f} kg, above the"
                         f" {safe_load:.0f} kg the pallet carries (its safe working load,"
                         f" evenly spread: pallet.safe_load_kg)")


def footprints_overlap(a: BundlePlacement, b: BundlePlacement, tol: float = 1e-6) -> bool:
    return all(
        abs(a.centre_m[k] - b.centre_m[k]) < (a.size_m[k] + b.size_m[k]) / 2 - tol for k in (0, 1)
    )


def _check_geometry(unit: LoadUnit, source: str) -> None:
    """Reject layouts that no bench could hold: no bundle fits, overhang, overlapping bundles."""
    p = unit.pallet
    layout = unit.layout()
    for layer in range(1, unit.stack.layers + 1):
        if not any(b.layer == layer for b in layout.bundles):
            raise InputError(source, "bundle",
                             f"no bundle fits on layer {layer} of the pallet with this pattern")
    for b in layout.bundles:
        over = max(
            abs(b.centre_m[0]) + b.size_m[0] / 2 - p.length_m / 2,
            abs(b.centre_m[1]) + b.size_m[1] / 2 - p.width_m / 2,
        )
        if over > OVERHANG_TOLERANCE_M:
            field_name = "stack.positions" if unit.stack.pattern == "explicit" else "bundle"
            raise InputError(source, field_name,
                             f"bundle {b.name} overhangs the pallet by {over * 1000:.0f} mm")
    first = [b for b in layout.bundles if b.layer == 1]
    for i, a in enumerate(first):
        for b in first[i + 1:]:
            if footprints_overlap(a, b):
                raise InputError(source, "stack.positions",
                                 f"bundles {a.name} and {b.name} overlap")
    for b in layout.bundles:
        if b.layer > 1 and not _supported(b, layout.bundles):
            raise InputError(source, "stack.pattern",
                             f"bundle {b.name} has its centre over no bundle of layer {b.layer - 1}"
                             " and would fall")


def _supported(b: BundlePlacement, bundles: tuple[BundlePlacement, ...]) -> bool:
    """Whether the centre of `b` lies over a bundle of the layer below (joints count as support)."""
    reach = BUNDLE_GAP_M + 1e-6
    return any(
        o.layer == b.layer - 1
        and all(abs(b.centre_m[k] - o.centre_m[k]) <= o.size_m[k] / 2 + reach for k in (0, 1))
        for o in bundles
    )


def check_unit(unit: LoadUnit, source: str) -> None:
    """Raise `InputError` (naming `source` and the field) for a unit no pallet or bench takes."""
    _check_limits(unit, source)
    _check_geometry(unit, source)
