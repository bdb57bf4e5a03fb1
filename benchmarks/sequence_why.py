"""Why a unit carried through the EUMOS levels ends where it does, against a fresh unit per level.

For each bundled example (as `benchmarks/sequence.py` runs them) and each level, in mm:

- `carried`: where the bundle whose permanent displacement since the unit was put on is largest
  stood, when the level began, from where it was put on (0 at the first level);
- `own`: the largest distance the level itself moved a bundle (from the level's start to its
  rest), on the carried unit and on a fresh one (`fresh`);
- how far the fresh figure moves under perturbations that carry nothing: `fresh ±2 %`, its
  range over levels 0.98, 0.99, 1.01 and 1.02 times the level's, and `after`, on a unit that
  first ran a level of 0.02 g;
- `total`: the largest permanent displacement since the unit was put on (what the 5 % criterion
  judges), and `along`: for its bundle, the cosine between the carried displacement and the
  level's own (1: the level pushed it on the way it had gone);
- for a wrapped unit, at the level's start: the rings' tension as a share of the tension laid
  (a fresh unit starts at 1 by construction: its rest lengths are set so), the largest
  plastic stretch of its rings and panels, in per mille, and `pull`, the wrap's largest net
  horizontal force on a layer, in g of that layer's weight (a web holding a layer back from
  where an earlier level left it). `end`: the same after the last level.

`--gap-mm` sets the gap the layout generator leaves between neighbouring bundles (2 mm,
assumed: docs/materials.md), for its sensitivity figure.

    python -m benchmarks.sequence_why [--target G] [--gap-mm MM]
"""

from __future__ import annotations

import argparse
import copy

import numpy as np

import wrapenv.load as load_module
from benchmarks.sequence import CASES, EXAMPLES
from wrapenv.bench import BenchUnit, run_level
from wrapenv.eumos import evaluate
from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import G, PulseProfile, eumos_levels
from wrapenv.trace import Trace, in_pallet_frame
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet


def _moves(trace: Trace) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) each bundle's carried displacement at the level's start and its own in the level,
    in the pallet's frame."""
    rel = in_pallet_frame(trace.pallet_pos_m, trace.pallet_rot, trace.bundle_pos_m)
    return (rel[0] - trace.origin())[:, :2], (rel[-1] - rel[0])[:, :2]


def _own_max_mm(trace: Trace) -> float:
    return 1000 * float(trace.bundle_displacement_m()[-1].max())


def _perturbed(layout: Layout, g: float, wrap: WrapFormat | None) -> str:
    """The fresh figure's range at levels within 2 % of `g`, and after a 0.02 g level."""
    near = [_own_max_mm(run_level(layout, PulseProfile(g * f), wrap=wrap))
            for f in (0.98, 0.99, 1.01, 1.02)]
    with BenchUnit(layout, wrap=wrap) as unit:
        unit.level(PulseProfile(0.02))
        after = _own_max_mm(unit.level(PulseProfile(g)))
    return f"{min(near):5.1f}-{max(near):<6.1f} {after:6.1f}"


def _layer_pull_g(net: WrapNet, trace: Trace) -> float:
    """The wrap's largest net horizontal force on a layer where `trace` ends, in g of the
    layer's weight (computed on a copy: the wrap's own state is left as it is)."""
    pos = np.vstack([trace.pallet_pos_m[-1:], trace.bundle_pos_m[-1]])
    rot = np.concatenate([trace.pallet_rot[-1:], trace.bundle_rot[-1]])
    still = np.zeros_like(pos)
    force = copy.deepcopy(net).forces(pos, rot, still, still)[0][1:, :2]
    mass = np.array([b.mass_kg for b in net.layout.bundles])
    layers = trace.layers if trace.layers is not None else np.ones(len(mass), int)
    return max(float(np.linalg.norm(force[layers == layer].sum(axis=0)))
               / (G * float(mass[layers == layer].sum()))
               for layer in np.unique(layers))


def _wrap_state(net: WrapNet, trace: Trace) -> str:
    """At the end of `trace`: the rings' tension as a share of the laid tension, the largest
    plastic stretch, and the wrap's largest pull on a layer."""
    laid = float(net.rings.pretension_n.sum())
    share = float(net.rings.last_n.sum()) / laid if laid > 0 else float("nan")
    plastic = net.report().plastic_strain_max
    return f"{share:9.2f} {1000 * plastic:9.2f} {_layer_pull_g(net, trace):7.3f}"


def _carried_row(trace: Trace) -> tuple[str, str, bool]:
    """The carried unit's columns (before and after the fresh unit's), and whether the sequence
    stops there (the level failed, as `benchmarks/sequence.py` stops at a failure)."""
    carried, own = _moves(trace)
    total = trace.permanent_total_m()
    worst = int(total.argmax())
    c, o = carried[worst], own[worst]
    lengths = float(np.linalg.norm(c) * np.linalg.norm(o))
    # nothing carried yet (the first level): no direction to compare, printed as "-"
    along = f"{float(c @ o) / lengths:5.2f}" if lengths > 1e-12 else f"{'-':>5}"
    return (f"{1000 * np.linalg.norm(c):7.1f} {_own_max_mm(trace):6.1f}",
            f"{1000 * total[worst]:7.1f} {along}",
            not evaluate(trace).passed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", type=float, default=0.5)
    parser.add_argument("--gap-mm", type=float, default=1000 * load_module.BUNDLE_GAP_M)
    args = parser.parse_args()
    load_module.BUNDLE_GAP_M = args.gap_mm / 1000  # read by each layout made after this
    print(f"gap between bundles {args.gap_mm:g} mm")
    print(f"{'load + wrap':42} {'level':>5} {'carried':>7} {'own':>6} {'fresh':>6} "
          f"{'fresh ±2 %':>12} {'after':>6} {'total':>7} {'along':>5}  {'tension':>9} "
          f"{'plastic':>9} {'pull':>7}")
    print(f"{'':42} {'g':>5} {'mm':>7} {'mm':>6} {'mm':>6} {'mm':>12} {'mm':>6} {'mm':>7} "
          f"{'cos':>5}  {'of laid':>9} {'‰':>9} {'g':>7}")
    for load_name, wrap_name in CASES:
        load = LoadUnit.from_toml(EXAMPLES / f"{load_name}.toml")
        wrap = (WrapFormat.from_toml(EXAMPLES / f"{wrap_name}.toml", load.load_height_m)
                if wrap_name else None)
        layout = load.layout()
        name = f"{load_name} + {wrap_name or 'unwrapped'}"
        with BenchUnit(layout, wrap=wrap) as unit:
            started = f"{'1.00 laid':>9}"
            for g in eumos_levels(args.target):
                trace = unit.level(PulseProfile(g))
                before, after, last = _carried_row(trace)
                fresh = _own_max_mm(run_level(layout, PulseProfile(g), wrap=wrap))
                print(f"{name:42} {g:5.1f} {before} {fresh:6.1f} "
                      f"{_perturbed(layout, g, wrap)} {after}  {started if wrap else ''}",
                      flush=True)
                name = ""
                if unit.wrap is not None:
                    started = _wrap_state(unit.wrap, trace)
                if last:
                    break
            if wrap is not None:
                print(f"{'':42} {'end':>5} {'':>62}{started}")


if __name__ == "__main__":
    main()
