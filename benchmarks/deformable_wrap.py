"""Baseline for the wrap model: a wrap built from PyBullet's own deformable world.

The project wraps loads with its own numpy cable-net model. This file builds the comparable wrap
from PyBullet 3.2.7's deformable world (`RESET_USE_DEFORMABLE_WORLD`, `loadSoftBody`): a
mass-spring cloth tube of `rings` x `nodes_around` nodes around a project load unit, its bottom
ring anchored to the pallet, shaken by the bench pulse applied as an inertial field. It reports
the wall time of the stepping loop and whether the run exploded.

Known limits of that API (bullet3 issues): no rest length or pretension, so the tube holds
nothing until the load moves into it (4142); parameters are fixed once loaded (2961); anchors to
moving rigid bodies are unstable (4070, PR 4687); deformables are not covered by save/restore.

    taskset -c 0 python -m benchmarks.deformable_wrap

PyBullet's C code prints a few lines ("argv[0]=", ...) that Python cannot silence.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import PulseProfile

if TYPE_CHECKING:  # for the annotations only: pybullet is imported where it is measured
    from pybullet_utils.bullet_client import BulletClient

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = {
    2: REPO / "examples" / "pet_2layer_columnar.toml",
    3: REPO / "examples" / "pet_3layer_columnar.toml",
}
G = 9.81
#: Gap between the load's outer rectangle and the tube, so the cloth starts out of contact.
WRAP_GAP_M = 0.005
#: Height of the tube's bottom ring: on the side of the pallet, where it is anchored.
BOTTOM_RING_Z_M = 0.07
WRAP_MASS_KG = 0.5
#: A node or body farther than this from where it started means the run blew up.
EXPLODE_DISTANCE_M = 5.0
CHECK_EVERY_STEPS = 24
DECK_SIZE_M = (4.0, 3.0, 0.1)
#: `springDampingStiffness`, damping along and across every spring (springDampingAllDirections).
#: Measured here at stiffness 1000 on the 3-layer unit, 0.5 g: PyBullet's default 0.1 blows up
#: within 0.1 s at both 240 and 500 Hz, even with no pulse and no anchors, and so does 1.0 with
#: damping along the springs only (springDampingAllDirections=0). With 1.0 in all directions the
#: tube runs 2 s at 500 Hz; at 240 Hz it blows up (~0.35 s) once the top-layer bundles slide into
#: it, with or without the anchors.
SPRING_DAMPING = 1.0


def _perimeter_points(half_x: float, half_y: float, n: int) -> list[tuple[float, float]]:
    """`n` points around a rectangle, counter-clockwise, with a point on every corner.

    The nodes of each side are shared out in proportion to its length, so the straight edges
    between nodes follow the rectangle instead of cutting its corners (which would start the
    cloth inside the load).
    """
    if n < 4:
        raise ValueError("nodes_around must be at least 4 (one per corner)")
    n_x = max(1, round(n / 2 * half_x / (half_x + half_y)))
    n_y = max(1, n // 2 - n_x)
    n_x = n // 2 - n_y
    extra = n - 2 * (n_x + n_y)  # odd n: one more node on the first long side
    corners = [(-half_x, -half_y), (half_x, -half_y), (half_x, half_y), (-half_x, half_y)]
    counts = [n_x + extra, n_y, n_x, n_y]
    pts = []
    for k, count in enumerate(counts):
        (x0, y0), (x1, y1) = corners[k], corners[(k + 1) % 4]
        for i in range(count):
            f = i / count
            pts.append((x0 + f * (x1 - x0), y0 + f * (y1 - y0)))
    return pts


def _write_tube_obj(path: Path, ring_xy: list[tuple[float, float]],
                    heights: np.ndarray) -> np.ndarray:
    """Write a closed triangulated band as Wavefront .obj; return its vertices (n, 3)."""
    n = len(ring_xy)
    verts = np.array([(x, y, z) for z in heights for x, y in ring_xy], dtype=float)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    for j in range(len(heights) - 1):
        for i in range(n):
            a = j * n + i + 1  # .obj indices start at 1
            b = j * n + (i + 1) % n + 1
            c, d = a + n, b + n
            lines.append(f"f {a} {b} {d}")
            lines.append(f"f {a} {d} {c}")
    path.write_text("\n".join(lines) + "\n")
    return verts


def _body_frictions(layout: Layout) -> tuple[float, float, float]:
    """Per-body coefficients (deck, pallet, bundle) whose products, as Bullet combines them,
    give the load's kinetic coefficient for each contact pair."""
    f = layout.friction
    bundle = math.sqrt(f.bundle_bundle.kinetic)
    pallet = f.pallet_bundle.kinetic / bundle
    deck = f.sled_pallet.kinetic / pallet
    return deck, pallet, bundle


def _mesh_nodes(client: BulletClient, pb: ModuleType, body: int) -> np.ndarray:
    _, pos = client.getMeshData(body, -1, flags=pb.MESH_DATA_SIMULATION_MESH)
    return np.asarray(pos, dtype=float).reshape(-1, 3)


def _exploded(client: BulletClient, pb: ModuleType, soft: int, rigid: list[int],
              node0: np.ndarray, rigid0: np.ndarray) -> bool:
    nodes = _mesh_nodes(client, pb, soft)
    pos = np.array([client.getBasePositionAndOrientation(b)[0] for b in rigid], dtype=float)
    if nodes.shape != node0.shape or not (np.all(np.isfinite(nodes)) and np.all(np.isfinite(pos))):
        return True
    far_nodes = np.linalg.norm(nodes - node0, axis=1).max() > EXPLODE_DISTANCE_M
    far_bodies = np.linalg.norm(pos - rigid0, axis=1).max() > EXPLODE_DISTANCE_M
    return bool(far_nodes or far_bodies)


def run_deformable_wrap(layers: int = 3, nodes_around: int = 24, rings: int = 7,
                        sim_seconds: float = 2.0, timestep_s: float = 1 / 240,
                        level_g: float = 0.5, stiffness: float = 1000.0,
                        damping: float = SPRING_DAMPING) -> dict:
    """Wrap the 2- or 3-layer columnar PET example in a PyBullet mass-spring tube and run the
    bench pulse for `sim_seconds`.

    Returns {"wall_s", "sim_s", "nodes", "timestep_s", "exploded", "realtime_factor"}:
    `wall_s` times the stepping loop only (not the building); `sim_s` is the simulated time
    actually run, shorter than `sim_seconds` when the run exploded (stepping stops there).
    `damping` is `springDampingStiffness` (see SPRING_DAMPING).
    """
    import pybullet as pb
    from pybullet_utils import bullet_client

    if layers not in EXAMPLES:
        raise ValueError(f"layers must be one of {sorted(EXAMPLES)} (got {layers})")
    if rings < 2:
        raise ValueError("rings must be at least 2")
    layout = LoadUnit.from_toml(EXAMPLES[layers]).layout()
    profile = PulseProfile(level_g)

    client = bullet_client.BulletClient(connection_mode=pb.DIRECT)
    try:
        client.resetSimulation(pb.RESET_USE_DEFORMABLE_WORLD)
        client.setTimeStep(timestep_s)
        client.setGravity(0, 0, -G)
        client.setPhysicsEngineParameter(sparseSdfVoxelSize=0.25)
        mu_deck, mu_pallet, mu_bundle = _body_frictions(layout)

        def box(size: tuple[float, float, float], centre: tuple[float, float, float],
                mass: float, mu: float) -> int:
            half = [s / 2 for s in size]
            col = client.createCollisionShape(pb.GEOM_BOX, halfExtents=half)
            body = client.createMultiBody(mass, col, -1, basePosition=list(centre))
            client.changeDynamics(body, -1, lateralFriction=mu, restitution=0.0,
                                  linearDamping=0.0, angularDamping=0.0,
                                  activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING)
            return body

        px, py, pz = layout.pallet_size_m
        box(DECK_SIZE_M, (0, 0, -DECK_SIZE_M[2] / 2), 0.0, mu_deck)
        pallet = box(layout.pallet_size_m, (0, 0, pz / 2), layout.pallet_mass_kg, mu_pallet)
        rigid = [pallet] + [box(b.size_m, b.centre_m, b.mass_kg, mu_bundle)
                            for b in layout.bundles]

        half_x = max([px / 2] + [abs(b.centre_m[0]) + b.size_m[0] / 2 for b in layout.bundles])
        half_y = max([py / 2] + [abs(b.centre_m[1]) + b.size_m[1] / 2 for b in layout.bundles])
        ring_xy = _perimeter_points(half_x + WRAP_GAP_M, half_y + WRAP_GAP_M, nodes_around)
        heights = np.linspace(BOTTOM_RING_Z_M, layout.load_height_m, rings)
        with tempfile.TemporaryDirectory() as tmp:
            obj = Path(tmp) / "wrap_tube.obj"
            verts = _write_tube_obj(obj, ring_xy, heights)
            soft = client.loadSoftBody(
                str(obj), basePosition=[0, 0, 0], scale=1.0, mass=WRAP_MASS_KG,
                useNeoHookean=0, useMassSpring=1, useBendingSprings=1,
                springElasticStiffness=stiffness, springDampingStiffness=damping,
                springDampingAllDirections=1, springBendingStiffness=0.1,
                useSelfCollision=0, frictionCoeff=0.5, useFaceContact=1,
                collisionMargin=0.002)
        node0 = _mesh_nodes(client, pb, soft)
        if node0.shape != verts.shape:
            raise RuntimeError(f"soft body has {len(node0)} nodes, the mesh {len(verts)}")
        # Bullet may reorder the .obj vertices: find the bottom ring by height, not by index.
        bottom = np.flatnonzero(node0[:, 2] < BOTTOM_RING_Z_M + 1e-4)
        for node in bottom:
            client.createSoftBodyAnchor(soft, int(node), pallet, -1)
        rigid0 = np.array([client.getBasePositionAndOrientation(b)[0] for b in rigid])

        steps = int(round(sim_seconds / timestep_s))
        exploded, done = False, 0
        t0 = time.perf_counter()
        for k in range(steps):
            client.setGravity(-float(profile.accel(k * timestep_s)), 0.0, -G)
            client.stepSimulation()
            done = k + 1
            if done % CHECK_EVERY_STEPS == 0 and _exploded(client, pb, soft, rigid, node0,
                                                           rigid0):
                exploded = True
                break
        wall = time.perf_counter() - t0
        if not exploded:
            exploded = _exploded(client, pb, soft, rigid, node0, rigid0)
    finally:
        client.disconnect()

    sim = done * timestep_s
    return {
        "wall_s": wall,
        "sim_s": sim,
        "nodes": int(len(node0)),
        "timestep_s": timestep_s,
        "exploded": exploded,
        "realtime_factor": sim / wall if wall > 0 else math.inf,
    }


def main() -> None:
    rows = []
    for timestep in (1 / 240, 1 / 500):
        rows.append(run_deformable_wrap(layers=3, nodes_around=24, rings=7, sim_seconds=2.0,
                                        timestep_s=timestep))
    print("PyBullet deformable wrap baseline, 3-layer columnar unit, 0.5 g pulse:")
    for r in rows:
        print(f"nodes {r['nodes']}  dt 1/{round(1 / r['timestep_s'])} s  "
              f"sim {r['sim_s']:.2f} s  wall {r['wall_s']:.2f} s  "
              f"real-time x{r['realtime_factor']:.2f}  exploded {r['exploded']}")


if __name__ == "__main__":
    main()
