"""The wrap's element law: tension-only, elastoplastic with linear hardening, tearing.

Arrays over elements (rings, panels), so the net updates them all in one call per step; and
how much less a web bears where it bends round a load's edge (`bend_curvature`, `bend_factor`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wrapenv.material import DAMPING_RATIO, Material

#: A fold round a sharp edge costs the web at most this fraction of its stretch to break: paper
#: is folded round carton edges at wrapping tension without tearing [A] (P7).
BEND_STRAIN_CAP = 0.5


def bend_factor(material: Material, bend_strain: np.ndarray) -> np.ndarray:
    """The web's break force over the force at which its membrane strain plus `bend_strain`
    (the outer fibre's, from bending round an edge) reach the break strain; the bending is
    capped at `BEND_STRAIN_CAP` of the break strain."""
    m = material
    left = m.break_strain - np.minimum(bend_strain, BEND_STRAIN_CAP * m.break_strain)
    k, ey = m.stiffness_n_per_m, m.yield_strain
    bearable = np.where(left <= ey, k * left, k * ey + m.hardening_ratio * k * (left - ey))
    return m.break_force_n_per_m / bearable


def bend_curvature(material: Material, edge_radius_m: np.ndarray, turn_rad: np.ndarray,
                   tension_n_per_m: np.ndarray) -> np.ndarray:
    """Curvature (1/m) of a web turned by `turn_rad` over an edge of this radius under this
    tension per metre of one layer's width. A tensioned web does not follow a kink sharply:
    its bending stiffness D = K t² / 12 spreads the turn over l = sqrt(D / T), so its sharpest
    bend is turn / (2 l) (a tensioned beam over a point), and no sharper than the edge."""
    t = material.layer_thickness_m
    stiffness = material.stiffness_n_per_m * t * t / 12.0
    length = np.sqrt(stiffness / np.maximum(tension_n_per_m, 1e-9))
    return np.minimum(1.0 / edge_radius_m, turn_rad / (2.0 * length))


@dataclass
class Elements:
    """Elastoplastic, tension-only elements with linear hardening; arrays over elements."""

    k_elastic_n_per_m: np.ndarray  # per metre of elongation
    plastic_modulus_n_per_m: np.ndarray    # hardening modulus H: the post-yield tangent is k_h
    yield_force_n: np.ndarray
    break_force_n: np.ndarray
    pretension_n: np.ndarray
    damping_n_s_per_m: np.ndarray
    height_m: np.ndarray           # where each element sits, for the report
    length_m: np.ndarray           # material length at freeze, for plastic strain

    def __post_init__(self) -> None:
        n = len(self.k_elastic_n_per_m)
        self.rest_m = np.zeros(n)
        self.plastic_m = np.zeros(n)
        self.torn = np.zeros(n, bool)
        self.opened = np.zeros(n, bool)   # slack for good: its seam let go (rings)
        self.peak = np.zeros(n)           # highest utilisation so far
        self.peak_force_n = np.zeros(n)
        self.peak_t_s = np.full(n, np.nan)
        self.rising = np.zeros(n, bool)   # whose peak rose at the last call
        self.last_n = self.pretension_n.copy()

    def force(self, length: np.ndarray, rate: np.ndarray, edge: np.ndarray | float = 1.0,
              t_s: float | None = None) -> np.ndarray:
        """Tension for the current lengths (return mapping of 1D plasticity), then tearing
        where tension times the `edge` factor reaches the breaking force."""
        trial = self.k_elastic_n_per_m * (length - self.rest_m - self.plastic_m)
        hardening = self.plastic_modulus_n_per_m * self.plastic_m
        over = trial - (self.yield_force_n + hardening)
        if over.max(initial=0.0) > 0:  # some element yields (most steps none does)
            flow = np.maximum(over, 0.0) / (self.k_elastic_n_per_m + self.plastic_modulus_n_per_m)
            self.plastic_m += flow
            trial = trial - self.k_elastic_n_per_m * flow
        elastic = np.where(self.torn | self.opened, 0.0, np.maximum(trial, 0.0))
        utilisation = elastic * edge / self.break_force_n
        self.rising = utilisation > self.peak
        if self.rising.any():
            self.peak = np.where(self.rising, np.minimum(utilisation, 1.0), self.peak)
            # a place that tore bore what it could: the force that reached its limit
            bore = np.minimum(elastic, self.break_force_n / edge)
            self.peak_force_n = np.where(self.rising, bore, self.peak_force_n)
            self.peak_t_s = np.where(self.rising, np.nan if t_s is None else t_s, self.peak_t_s)
        self.torn |= utilisation >= 1.0
        self.last_n = np.where(self.torn, 0.0, elastic)
        taut = self.last_n > 0
        return np.where(taut, np.maximum(self.last_n + self.damping_n_s_per_m * rate, 0.0), 0.0)


def series(*k: np.ndarray | float) -> np.ndarray:
    return np.asarray(1.0 / sum(1.0 / np.asarray(x, float) for x in k))


def element_set(k_web_n_per_m: np.ndarray, material_strength: tuple[float, float, float],
                 web_m: np.ndarray, pretension_n: np.ndarray, mass_kg: np.ndarray,
                 height_m: np.ndarray, length_m: np.ndarray, give_n_per_m: np.ndarray | float,
                 damping_ratio: float = DAMPING_RATIO) -> Elements:
    """Elements from the web's stiffness, the metres of web they stand for, and the load's
    give at their ends (in series with the web), each damped at `damping_ratio` of critical
    for its stiffness and the masses it joins.

    `material_strength` is (yield force per metre, break force per metre, hardening ratio).
    """
    yield_per_m, break_per_m, hardening = material_strength
    k_e = series(k_web_n_per_m, give_n_per_m)
    k_h = series(np.maximum(k_web_n_per_m * hardening, 1e-9), give_n_per_m)
    plastic_modulus_n_per_m = k_e * k_h / np.maximum(k_e - k_h, 1e-9)
    return Elements(
        k_elastic_n_per_m=k_e,
        plastic_modulus_n_per_m=plastic_modulus_n_per_m,
        yield_force_n=yield_per_m * web_m,
        break_force_n=np.maximum(break_per_m * web_m, 1e-9),
        pretension_n=pretension_n,
        damping_n_s_per_m=2 * damping_ratio * np.sqrt(k_e * mass_kg),
        height_m=height_m,
        length_m=length_m,
    )
