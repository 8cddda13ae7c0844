"""Random pick-and-place workcell tasks, the kind an integrator sets up, as task files.

Each task, drawn from a seed: the UR5e at the world origin on its table, the tool
pointing down (E's z axis, ``euler_zyx = [0, -pi/2, 0]`` with the bundled libraries'
tool frame), four critical configurations:

1. grasp at (x_g, y_g, 0.1) with the yaw about the vertical free in [-pi/2, pi/2];
2. lift 25 cm straight up;
3. carry to above the place position at the same height;
4. place at (x_p, y_p, 0.1).

Grasp and place are drawn on opposite sides of the robot's x axis, 0.3-0.6 m out and
0.15-0.45 m to the side; in most tasks (``obstacle_probability``) a box obstacle
0.08-0.15 m wide and 0.10-0.18 m high stands on the table halfway between them, inside
a safety shell 3 cm larger on every side, so the carry must pass over it.

With ``shell_near_base``, a second shell stands beside the robot (12-30 cm from the
base axis, at any bearing), as guards and racks crowd a real cell: the arm's shoulder and upper
arm pass near it as shoulder_pan turns, so some tasks can only be refused.

Not for: running them (``benchmarks/bench_pick_and_place.py``, ``simulation.py``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["LIFT_M", "GRASP_Z_M", "pick_and_place_yaml", "write_pick_and_place_tasks"]

LIFT_M = 0.25
GRASP_Z_M = 0.1
SHELL_MARGIN_M = 0.03
TOOL_FRAME = "{p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}"


def _fmt(values) -> str:
    return "[" + ", ".join(f"{float(v):.4f}" for v in values) + "]"


def pick_and_place_yaml(seed: int, *, obstacle_probability: float = 0.8, shell_near_base: bool = False) -> str:
    """The task file of pick-and-place task ``seed`` (see the module docstring).

    ``shell_near_base``: also a safety shell beside the robot (:func:`_base_shell`), drawn
    from the same seed after everything else, so the task is otherwise the same."""
    rng = np.random.default_rng(seed)
    side = 1.0 if rng.random() < 0.5 else -1.0
    grasp = np.array([rng.uniform(0.3, 0.6), side * rng.uniform(0.15, 0.45), GRASP_Z_M])
    place = np.array([rng.uniform(0.3, 0.6), -side * rng.uniform(0.15, 0.45), GRASP_Z_M])
    lift = grasp + [0.0, 0.0, LIFT_M]
    above = place + [0.0, 0.0, LIFT_M]
    lines = [
        f"name: pick_and_place_{seed}",
        "description: grasp, lift 25 cm, carry over the box, place (tool down)",
        "X_WB: {p: [0, 0, 0], euler_zyx: [0, 0, 0]}",
        f"X_tool0_E: {TOOL_FRAME}",
        "critical_configurations:",
        f"  - {{p: {_fmt(grasp)}, euler_zyx: [[-pi/2, pi/2], -pi/2, 0]}}   # grasp, yaw free",
        f"  - {{p: {_fmt(lift)}, euler_zyx: [0, -pi/2, 0]}}   # lifted",
        f"  - {{p: {_fmt(above)}, euler_zyx: [0, -pi/2, 0]}}   # above the place",
        f"  - {{p: {_fmt(place)}, euler_zyx: [0, -pi/2, 0]}}   # placed",
    ]
    if rng.random() < obstacle_probability:
        width = rng.uniform(0.08, 0.15, 2)
        height = rng.uniform(0.10, 0.18)
        centre = np.append(0.5 * (grasp[:2] + place[:2]), height / 2)
        size = np.append(width, height)
        shell_size = size + 2 * SHELL_MARGIN_M
        shell_centre = centre.copy()
        shell_centre[2] = shell_size[2] / 2
        lines += [
            "obstacles:",
            f"  - {{name: box, centre: {_fmt(centre)}, size: {_fmt(size)}}}",
            "safety_shells:",
            f"  - {{name: box_shell, centre: {_fmt(shell_centre)}, size: {_fmt(shell_size)}}}",
        ]
    if shell_near_base:
        centre, size = _base_shell(rng)
        if "safety_shells:" not in lines:
            lines.append("safety_shells:")
        lines.append(f"  - {{name: base_shell, centre: {_fmt(centre)}, size: {_fmt(size)}}}")
    return "\n".join(lines) + "\n"


def _base_shell(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A keep-out shell standing on the table beside the robot, as a guard around a
    machine's door or a parts rack leaves one (centre, size): 10-25 cm wide, 20-60 cm
    high, its near face 12-30 cm from the base axis at a random bearing, so the
    shoulder's and the upper arm's sweeps in shoulder pan pass near it one way round or
    both (and, in front, the tool may have to pass over it)."""
    width = rng.uniform(0.10, 0.25, 2)
    height = rng.uniform(0.20, 0.60)
    bearing = rng.uniform(0.0, 2 * np.pi)
    near = rng.uniform(0.12, 0.30)
    distance = near + 0.5 * float(width.max())
    centre = np.array([distance * np.cos(bearing), distance * np.sin(bearing), height / 2])
    return centre, np.append(width, height)


def write_pick_and_place_tasks(directory: Path, count: int, first_seed: int = 0) -> list[Path]:
    """Writes ``count`` task files ``pick_and_place_<seed>.yaml`` into ``directory``."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for seed in range(first_seed, first_seed + count):
        path = directory / f"pick_and_place_{seed}.yaml"
        path.write_text(pick_and_place_yaml(seed))
        paths.append(path)
    return paths
