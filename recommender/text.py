"""What `wrapbench` prints: the level table of a verdict and the wrapping program as an
operator enters it, with the web it lays and the time it takes."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from wrapenv.bench import BenchRun, SimSettings
from wrapenv.calibrated import Calibration
from wrapenv.config import printable
from wrapenv.eumos import NO_DAMAGE, LevelVerdict, Verdict
from wrapenv.load import Layout, LoadUnit, Orientation
from wrapenv.material import NO_RELAXATION, Material
from wrapenv.profile import Profile, g_text
from wrapenv.program import Pass, Program
from wrapenv.wrap import WrapFormat


def _mm(x: float | None) -> str:
    return "   n/a" if x is None else f"{x * 1000:6.1f}"


def _pct(x: float | None, height_m: float) -> str:
    return "      " if x is None else f"({100 * x / height_m:4.1f} %)"


def mm_text(x: float | None) -> str:
    """A figure in mm as a sentence gives it; one a blown-up run could not give (null) is
    "n/a", not 0 mm."""
    return "n/a" if x is None else f"{1000 * x:.1f} mm"


def sample_figures(level: dict[str, Any]) -> str:
    """A sample's level (its JSON) in the two figures a worst-sample line gives, printed and
    in the HTML report."""
    return (f"elastic {mm_text(level.get('elastic_max_m'))}, permanent "
            f"{mm_text(level.get('permanent_max_m'))}")


def level_result(verdict: Verdict, v: LevelVerdict) -> str:
    """PASS, FAIL or INVALID; a level that met its criteria in a run that later blew up is
    VOID: it is not reported as passed."""
    if verdict.reported_passed(v):
        return "PASS"
    return "INVALID" if not v.valid else ("FAIL" if not v.passed else "VOID")


#: Why a wrapped unit's run most likely blew up (README, "What it cannot hold").
TIGHT_WRAP_HINT = ("; on a wrapped unit most often a wrap squeezing light bundles far harder "
                   "than they weigh: try a gentler tension")


def wrapped(verdict: Verdict) -> bool:
    """Whether the levels were run on a wrapped unit."""
    return any(level.wrap is not None for level in verdict.levels)


def _criterion_name(v: LevelVerdict, key: str) -> str:
    """A failed criterion as the limits line above the table names it ("permanent max"), not
    by its JSON key ("permanent_5pct")."""
    if key == NO_DAMAGE:
        return "damage"
    named = {c.key: c.label.lower().replace(", ", " ") for c in v.limits.criteria()}
    return named.get(key, key)


def _row(verdict: Verdict, v: LevelVerdict, height_m: float) -> str:
    result = level_result(verdict, v)
    failed = [_criterion_name(v, k) for k, ok in v.criteria.items() if not ok]
    ended = [why for why in (v.stopped_early, v.not_at_rest) if why]
    note = v.invalid_reason or ", ".join(failed + ended)
    damage = f"; {len(v.damage)} damaged: {', '.join(v.damage[:4])}" if v.damage else ""
    if len(v.damage) > 4:
        damage += ", ..."
    total = v.permanent_total_max_m
    return (f"{g_text(v.level_g):>5} g  {result:7s} {_mm(v.elastic_max_m)} "
            f"{_pct(v.elastic_max_m, height_m)}  {_mm(v.permanent_max_m)} {_mm(total)} "
            f"{_pct(total, height_m)}  {_mm(v.permanent_low20_m)}"
            f"  {_mm(v.layer_shift_max_m)} {_pct(v.layer_shift_max_m, height_m)}"
            f"  {_mm(v.pallet_slip_m)}  {note}{damage}")


def orientation_tested(load: LoadUnit, orientation: Orientation | None) -> Orientation:
    """Which side of the pallet faced the motion: "long" or "short" (a square pallet's is
    "long"), as asked or as the load file lays the unit out (its length along x)."""
    if orientation is not None:
        return orientation
    return "long" if load.pallet.length_m >= load.pallet.width_m else "short"


def sequence_text(verdict: Verdict) -> str:
    """How the levels were run, in words: one level has no sequence to speak of."""
    if len(verdict.levels) == 1:
        wrapped = verdict.levels[0].wrap is not None
        return "one level, on the unit as stacked" + (" and wrapped" if wrapped else "")
    if verdict.sequence == "cumulative":
        return "one unit through the levels, each from where the last left it"
    return "a fresh unit for every level"


def verdict_table(load: LoadUnit, run: BenchRun, orientation: Orientation | None) -> str:
    """The unit, the sequence, the criteria, one row per level run, the highest level passed.
    Figures in mm; "permanent" is this level's, then since the unit was put on the sled (what
    the criterion judges)."""
    layout = load.layout(orientation)
    v = run.verdict
    h = v.load_height_m
    criteria = v.criteria()
    limits = ", ".join(f"{c.label.lower()} {c.describe(h)}" for c in criteria)
    lines = [
        f"{printable(load.name)}: {len(layout.bundles)} bundles, {load.stack.layers} "
        f"layer{'s' * (load.stack.layers != 1)} ({load.stack.pattern}), load height {h:.3f} m, "
        f"{load.mass_kg:.0f} kg",
        f"sequence: {v.sequence} ({sequence_text(v)}); motion along the pallet's "
        f"{orientation_tested(load, orientation)} side ({layout.pallet_size_m[0]:.3f} m)",
        f"limits: {limits}, no damage",
        "figures in mm (% of load height); permanent: during the level, then since the unit "
        "was put on the sled; pallet slip: on the sled, during the level",
        f"{'level    result':17}{'elastic max':>15}  {'permanent':>6} {'total':>15}  "
        f"{'low20cm':>6}  {'layer shift':>15}  {'pallet slip':>6}",
    ]
    lines += [_row(v, level, h).rstrip() for level in v.levels]
    torn = [f"{g_text(level.level_g)} g" for level in v.levels if level.wrap and level.wrap.torn]
    if torn:
        lines.append(f"wrap torn at: {', '.join(torn)}")
    best = v.highest_passed_g
    lines.append(f"highest level passed: {'none' if best is None else g_text(best) + ' g'}"
                 + ("" if v.valid else f"  (simulation became unphysical: see INVALID rows"
                                       f"{TIGHT_WRAP_HINT if wrapped(v) else ''})"))
    if rerun := rerun_note(run):
        lines.append(rerun)
    return "\n".join(lines)


def rerun_note(run: BenchRun) -> str:
    """A line when the run had to be made again with more solver iterations ("" if not)."""
    if not run.unsolved_at:
        return ""
    tried = ", ".join(f"at {iterations} it {why}" for iterations, why in run.unsolved_at)
    return (f"solved with {run.solver_iterations} solver iterations: the squeezed stack (a wrap "
            f"many times the bundles' weight) was not solved with fewer ({tried})")


def _carriage(p: Pass, wrap: WrapFormat, load_height_m: float) -> str:
    """Where the web's lower edge is; a spiral's carriage speed too, which a panel may ask
    for instead of the overlap (the rise per revolution times the rpm)."""
    if p.travel_m > 0:
        return f"{p.start_m:.3f} -> {p.end_m:.3f} m at {p.rise_m * wrap.rpm:.1f} m/min"
    text = f"{p.start_m:.3f} m"
    if p.rope_m is not None:
        return text + " (roped)"
    above = p.start_m + wrap.web_width_m - load_height_m
    return text + (f" (web {above:.2f} m above the load)" if above > 1e-9 else "")


def step_cells(p: Pass, wrap: WrapFormat, load_height_m: float) -> tuple[str, ...]:
    """One step of a program as an operator reads it (printed and in the HTML report): zone,
    wraps, overlap, carriage (the web's lower edge), tension in N."""
    turns = f"{p.turns:g}" if p.travel_m == 0 else f"{p.turns:.2f}"
    overlap = f"{100 * (1 - p.rise_m / wrap.web_width_m):.0f} %" if p.travel_m > 0 else "-"
    return p.zone, turns, overlap, _carriage(p, wrap, load_height_m), f"{p.tension_n:.1f}"


def _step(i: int, p: Pass, wrap: WrapFormat, load_height_m: float) -> str:
    zone, turns, overlap, carriage, tension = step_cells(p, wrap, load_height_m)
    return f"{i:4d}  {zone:<14}{turns:>6}  {overlap:>7}  {carriage:<34}{tension:>9}"


def program_text(wrap: WrapFormat, layout: Layout) -> str:
    """The program step by step (what the carriage does, in order), then the web it lays and
    the cycle time. A band form is listed as the full-width revolutions a machine needs."""
    what = "wrapping program" if wrap.program is not None else "bands, laid as"
    stretch = wrap.prestretch
    prestretch = f", pre-stretch {100 * stretch:.0f} %" if stretch is not None else ""
    lines = [f"{what}: {printable(wrap.material.name)}, web {wrap.web_width_m:.2f} m"
             f"{prestretch}, {wrap.rpm:g} rpm",
             "step  zone           wraps  overlap  carriage (web's lower edge)        tension N"]
    lines += [_step(i, p, wrap, layout.load_height_m) for i, p in enumerate(wrap.passes, 1)]
    used = wrap.material_used_on(layout)
    roll = (f", {used.roll_length_m:.1f} m from the roll"
            if abs(used.roll_length_m - used.web_length_m) > 1e-9 else "")
    lines.append(f"material used: {used.area_m2:.2f} m² of web ({used.mass_kg:.3f} kg), "
                 f"{used.web_length_m:.1f} m laid{roll}, {used.revolutions:.1f} revolutions")
    lines.append(f"cycle time: {wrap.cycle_time_s:.0f} s, {wrap.pallets_per_hour:.0f} pallets/h "
                 f"({machine_text(wrap)})")
    return "\n".join(lines)


def machine_text(wrap: WrapFormat) -> str:
    """The machine a program's cycle time is for, as the text and the page give it."""
    m = wrap.machine
    return (f"{wrap.rpm:g} rpm, {m.ramp_s:g} s to start and to stop, carriage up to "
            f"{m.carriage_speed_mps:g} m/s, {m.handling_s:.0f} s to change pallets")


def conditions_text(profiles: Sequence[Profile], run: BenchRun) -> str:
    """How the levels were run (at the bench's default settings, as `simulate` and
    `recommend` run them), as a test report states its conditions: the sled's motion, the
    unit's settling, the bench's time step and solve."""
    settings = SimSettings()
    motions = list(dict.fromkeys(p.describe() for p in profiles))
    return (f"sled: {'; '.join(motions)}; the unit first settles {settings.settle_s:g} s on the "
            f"still sled; bench: PyBullet, time step 1/{1 / settings.timestep_s:.0f} s, "
            f"{run.solver_iterations} solver iterations")


def age_text(material: Material, hours_since_wrapping: float) -> str:
    """How old the wrap was when tested, and what its tension kept."""
    if hours_since_wrapping == 0:
        return ("wrap tested as just laid (0 h after wrapping; a lab tests it after it stood: "
                "--hours-since-wrapping)")
    kept = material.relaxation.retained(hours_since_wrapping)
    how = "relaxes" if material.relaxation != NO_RELAXATION else "does not relax, by its card"
    return (f"wrap tested {hours_since_wrapping:g} h after wrapping: its tension {kept:.0%} of "
            f"what was laid ({printable(material.name)} {how})")


def calibration_text(source: str, calibration: Calibration, simulated: LoadUnit,
                     wrapped: bool) -> str:
    """Which values a calibration put in place, as simulated (a pair it leaves out, or one it
    only bounds below the load file's value, keeps the load file's)."""
    pairs = ", ".join(f"{name} {simulated.friction.pair(name).static:.3f} / "
                      f"{simulated.friction.pair(name).kinetic:.3f}"
                      + _unidentified(calibration.friction[name].static,
                                      simulated.friction.pair(name).static,
                                      calibration.friction[name].identified)
                      for name in calibration.friction)
    parts = [f"friction (static / kinetic) {pairs}" if pairs else "no friction pair"]
    if wrapped:
        parts.append(f"web stiffness x {calibration.stiffness_scale:.2f}, laid tension x "
                     f"{calibration.tension_scale:.2f}")
    if calibration.give_scale != 1.0:
        parts.append(f"the load's give x {calibration.give_scale:.2f}")
    return f"calibrated by {printable(source)}: " + "; ".join(parts)


def _unidentified(bound: float, simulated: float, identified: bool) -> str:
    """Where a pair the recordings never saw slip got its value: CAL.json only bounds it."""
    if identified:
        return ""
    if simulated > bound + 1e-12:
        return f" (not identified: the load file's, above CAL.json's bound {bound:.3f})"
    return " (not identified: CAL.json's lower bound)"


def program_summary(program: Program) -> str:
    """One line: what an operator sets, zone by zone."""
    parts = [f"{program.bottom_wraps} bottom wraps at {program.bottom_tension_n:.0f} N"
             + (" (roped)" if program.roping else ""),
             f"spiral up {100 * program.up_overlap:.0f} % at {program.middle_tension_n:.0f} N"]
    parts += [f"{r.wraps} at {r.from_m:.2f} m at {r.tension_n:.0f} N"
              for r in program.reinforcements]
    parts.append(f"{program.top_wraps} top wraps at {program.top_tension_n:.0f} N")
    if program.down_overlap is not None:
        parts.append(f"spiral down {100 * program.down_overlap:.0f} %")
    return ", ".join(parts)
