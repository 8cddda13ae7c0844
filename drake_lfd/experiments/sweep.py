"""A sweep over robot base placements: the grid, one JSON row per trial, the summary and its figures.

``drake-lfd sweep`` runs N trials of a task at every base placement of a grid
(:class:`BaseGrid`, parsed from ``--base-grid X0:X1:NX Y0:Y1:NY [Z0:Z1:NZ]
[YAW0:YAW1:NYAW]``; an axis not given keeps the task's value). Each finished trial is one
row (:func:`sweep_row`): its inputs (the base placement, trial, seed, the concrete
values of the task's variables), then the fields of ``simulate``'s trial records. A
row's inputs are its key (:func:`row_key`): ``--resume`` skips the trials whose key is on
disk. :func:`sweep_summary` aggregates the rows (success per base placement, the best
placements, failures by kind, :func:`failure_kinds_of`), and three figures show them:
success over the base grid, over the task's variables, and the failures by kind.

Not for: running trials (:mod:`drake_lfd.experiments.parallel_trials`) or the command line.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from drake_lfd.core.errors import InputError
from drake_lfd.experiments.figures import save_figure
from drake_lfd.experiments.parallel_trials import BasePlacement
from drake_lfd.experiments.simulation import trial_json

__all__ = [
    "BASE_FIELDS",
    "BaseGrid",
    "parse_axis",
    "base_grid",
    "sweep_row",
    "row_key",
    "failure_kinds_of",
    "sweep_summary",
    "success_by_base_figure",
    "success_by_variable_figure",
    "failure_reasons_figure",
]

#: A row's base placement fields: metres, metres, metres, degrees.
BASE_FIELDS = ("base_x", "base_y", "base_z", "base_yaw_deg")
_AXIS_NAMES = ("X", "Y", "Z", "YAW")
_KEY_DIGITS = 9  # base coordinates are matched to a nanometre (a nano-degree)


@dataclasses.dataclass(frozen=True)
class BaseGrid:
    """The values of each axis (x, y, z in m; yaw in deg); placements are every combination."""

    x: tuple
    y: tuple
    z: tuple
    yaw_deg: tuple

    def placements(self) -> list[BasePlacement]:
        """Every placement, x slowest, then y, z, yaw."""
        return [BasePlacement(*values) for values in itertools.product(self.x, self.y, self.z, self.yaw_deg)]

    def as_json(self) -> dict:
        return {"x": list(self.x), "y": list(self.y), "z": list(self.z), "yaw_deg": list(self.yaw_deg)}


def parse_axis(text: str, name: str = "X") -> tuple:
    """``"A:B:N"`` -> N evenly spaced values from A to B (N >= 1; with N = 1, A must equal B).

    Raises
    ------
    InputError
        ``--base-grid: "0:1:x" is not X0:X1:N``, or what is wrong with N.
    """
    parts = str(text).split(":")
    pattern = f"{name}0:{name}1:N{name}"
    try:
        if len(parts) != 3:
            raise ValueError
        lower, upper, count = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise InputError(f'"{text}" is not {pattern}', field="--base-grid") from None
    if not (math.isfinite(lower) and math.isfinite(upper)):
        raise InputError(f'"{text}": {name}0 and {name}1 must be finite numbers', field="--base-grid")
    if count < 1:
        raise InputError(f'"{text}": N{name} must be at least 1, got {count}', field="--base-grid")
    if count == 1 and lower != upper:
        raise InputError(f'"{text}": one point needs {name}0 = {name}1', field="--base-grid")
    # rounded to 12 decimals, so -0.3:-0.1:3 gives -0.2, not -0.19999999999999998
    return tuple(round(float(v), 12) for v in np.linspace(lower, upper, count))


def base_grid(axes: list[str] | None, task_base: BasePlacement) -> BaseGrid:
    """The grid of ``--base-grid`` (2 to 4 axes: x, y, then optionally z and yaw); the
    axes not given (all of them without ``axes``) keep the task's base value."""
    axes = list(axes or [])
    if axes and not 2 <= len(axes) <= 4:
        raise InputError(f"expected 2 to 4 axes (X0:X1:NX Y0:Y1:NY [Z0:Z1:NZ] [YAW0:YAW1:NYAW]), "
                         f"got {len(axes)}", field="--base-grid")
    own = (task_base.x, task_base.y, task_base.z, task_base.yaw_deg)
    values = [parse_axis(text, name) for text, name in zip(axes, _AXIS_NAMES)]
    values += [(own[i],) for i in range(len(values), 4)]
    return BaseGrid(*values)


def sweep_row(*, task_name: str, library: str, options: dict, policy: str | None, base: BasePlacement,
              variables: dict, outcome) -> dict:
    """One row of ``sweep.jsonl``: the inputs (``options``: the planner options, such as
    ``{"planner": "exact", ...}``), then ``simulate``'s trial record fields."""
    return {
        "task": task_name, "library": library, "options": dict(options), "policy": policy,
        "base_x": base.x, "base_y": base.y, "base_z": base.z, "base_yaw_deg": base.yaw_deg,
        "variables": {name: float(value) for name, value in variables.items()},
        **trial_json(outcome),
    }


def row_key(row: dict) -> tuple:
    """What identifies a row's trial: task, library, planner options, policy, base
    placement, trial and seed."""
    return (row["task"], row["library"], tuple(sorted(row["options"].items())), row["policy"],
            *(round(float(row[name]), _KEY_DIGITS) for name in BASE_FIELDS), int(row["trial"]), int(row["seed"]))


def failure_kinds_of(row: dict) -> list[str]:
    """The failure labels of a row (``failure_kinds``: ``"no executable plan (reach)"``,
    ``"penetration"``, ... from each failure record's kind, :mod:`drake_lfd.core.failures`);
    ``"other"`` for each failure of a row written before rows carried them."""
    return list(row.get("failure_kinds") or ["other"] * len(row["failures"]))


def _placement(row: dict) -> tuple:
    return tuple(float(row[name]) for name in BASE_FIELDS)


def sweep_summary(rows: list[dict], *, grid: BaseGrid, task_base: BasePlacement, settings: dict) -> dict:
    """``summary.json``: the settings, the grid, success per base placement (grid order),
    the best placements (highest success rate) and the failures by kind (a trial counts
    once per kind)."""
    by_placement: dict[tuple, list[dict]] = {}
    for row in rows:
        by_placement.setdefault(_placement(row), []).append(row)
    by_base = []
    for placement in grid.placements():
        key = (placement.x, placement.y, placement.z, placement.yaw_deg)
        group = by_placement.get(key, [])
        successes = sum(bool(r["success"]) for r in group)
        by_base.append({**dict(zip(BASE_FIELDS, key)), "trials": len(group), "successes": successes,
                        "success_rate": successes / len(group) if group else None})
    rated = [entry for entry in by_base if entry["trials"]]
    best_rate = max((entry["success_rate"] for entry in rated), default=None)
    kinds: dict[str, int] = {}
    for row in rows:
        for kind in sorted(set(failure_kinds_of(row))):
            kinds[kind] = kinds.get(kind, 0) + 1
    return {
        **settings,
        "grid": grid.as_json(),
        "task_base": dict(zip(BASE_FIELDS, (task_base.x, task_base.y, task_base.z, task_base.yaw_deg))),
        "rows": len(rows),
        "success_count": sum(bool(r["success"]) for r in rows),
        "by_base": by_base,
        "best": [entry for entry in rated if entry["success_rate"] == best_rate],
        "failure_kinds": dict(sorted(kinds.items(), key=lambda item: (-item[1], item[0]))),
    }


def _cell_text(successes: int, trials: int) -> str:
    return f"{successes}/{trials}" if trials else "-"


def success_by_base_figure(path, summary: dict, *, title: str) -> Path:
    """Heatmap of the success rate over the base grid's x and y (cells say k/n), one
    panel per (z, yaw) of the grid; the task's own base is outlined (its cell) or
    starred (between cells)."""
    grid = summary["grid"]
    xs, ys, zs, yaws = grid["x"], grid["y"], grid["z"], grid["yaw_deg"]
    panels = list(itertools.product(zs, yaws))
    columns = min(len(panels), 4)
    rows_count = math.ceil(len(panels) / columns)
    figure = Figure(figsize=(max(6.4, 1.2 + 3.6 * columns), 0.9 + 3.2 * rows_count), layout="constrained")
    axes = np.atleast_1d(figure.subplots(rows_count, columns, squeeze=False)).ravel()
    entries = {(e["base_x"], e["base_y"], e["base_z"], e["base_yaw_deg"]): e for e in summary["by_base"]}
    image = None
    own = summary["task_base"]
    for axis, (z, yaw) in zip(axes, panels):
        rate = np.full((len(ys), len(xs)), np.nan)
        for i, x in enumerate(xs):
            for j, y in enumerate(ys):
                entry = entries[(x, y, z, yaw)]
                if entry["trials"]:
                    rate[j, i] = entry["success_rate"]
                axis.text(i, j, _cell_text(entry["successes"], entry["trials"]), ha="center", va="center",
                          fontsize=8, bbox={"facecolor": "white", "alpha": 0.7, "edgecolor": "none", "pad": 1})
        image = axis.imshow(rate, origin="lower", cmap="RdYlGn", vmin=0.0, vmax=1.0, aspect="auto")
        axis.set_xticks(range(len(xs)), [f"{x:.3g}" for x in xs], rotation=45)
        axis.set_yticks(range(len(ys)), [f"{y:.3g}" for y in ys])
        axis.set_xlabel("base x (m)")
        axis.set_ylabel("base y (m)")
        if len(panels) > 1:
            axis.set_title(f"z {z:.3g} m, yaw {yaw:.3g} deg", fontsize=9)
        if (xs[0] <= own["base_x"] <= xs[-1] and ys[0] <= own["base_y"] <= ys[-1]
                and math.isclose(own["base_z"], z) and math.isclose(own["base_yaw_deg"], yaw)):
            column = np.interp(own["base_x"], xs, range(len(xs))) if len(xs) > 1 else 0.0
            row = np.interp(own["base_y"], ys, range(len(ys))) if len(ys) > 1 else 0.0
            if np.isclose(column, round(column)) and np.isclose(row, round(row)):  # a grid cell: outline it
                axis.add_patch(Rectangle((round(column) - 0.5, round(row) - 0.5), 1, 1, fill=False, edgecolor="k",
                                         linewidth=2.5, label="task file's base"))
            else:
                axis.plot([column], [row], marker="*", color="k", markersize=14, markerfacecolor="none",
                          linestyle="none", label="task file's base")
            axis.legend(loc="upper right", fontsize=7)
    for axis in axes[len(panels):]:
        axis.set_visible(False)
    figure.colorbar(image, ax=list(axes[:len(panels)]), label="success rate")
    figure.suptitle(title, fontsize=10)
    return save_figure(figure, path)


def success_by_variable_figure(path, rows: list[dict], *, title: str) -> Path:
    """Success over the task's variables: with two or more, a scatter over the first two
    (sorted by name); with one, the success rate in ten bins of its range; with none,
    the success rate per trial seed."""
    names = sorted({name for row in rows for name in row["variables"]})
    figure = Figure(figsize=(6.4, 4.8), layout="constrained")
    axis = figure.subplots()
    success = np.array([bool(r["success"]) for r in rows], dtype=bool)
    if len(names) >= 2:
        first = np.array([r["variables"].get(names[0], np.nan) for r in rows], dtype=float)
        second = np.array([r["variables"].get(names[1], np.nan) for r in rows], dtype=float)
        axis.scatter(first[success], second[success], marker="o", color="tab:green", label="success")
        axis.scatter(first[~success], second[~success], marker="x", color="tab:red", label="failed")
        axis.set_xlabel(names[0])
        axis.set_ylabel(names[1])
        axis.legend()
    elif names:
        values = np.array([r["variables"][names[0]] for r in rows], dtype=float)
        edges = np.linspace(values.min(), values.max(), 11) if len(values) and values.max() > values.min() \
            else np.array([values.min() - 0.5, values.min() + 0.5]) if len(values) else np.array([0.0, 1.0])
        bins = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, len(edges) - 2)
        counts = np.bincount(bins, minlength=len(edges) - 1)
        hits = np.bincount(bins, weights=success.astype(float), minlength=len(edges) - 1)
        rate = np.divide(hits, counts, out=np.full(len(counts), np.nan), where=counts > 0)
        centres = 0.5 * (edges[:-1] + edges[1:])
        axis.bar(centres, np.nan_to_num(rate), width=np.diff(edges) * 0.9, color="tab:green")
        for centre, count, hit in zip(centres, counts, hits):
            if count:
                axis.text(centre, 1.02, f"{int(hit)}/{count}", ha="center", fontsize=7)
        axis.set_xlabel(names[0])
        axis.set_ylabel("success rate")
        axis.set_ylim(0, 1.1)
    else:
        seeds = sorted({int(r["seed"]) for r in rows})
        rate = [np.mean([bool(r["success"]) for r in rows if int(r["seed"]) == s]) for s in seeds]
        axis.bar([str(s) for s in seeds], rate, color="tab:green")
        axis.set_xlabel("trial seed (the task has no variables)")
        axis.set_ylabel("success rate over the base grid")
        axis.set_ylim(0, 1.05)
    axis.set_title(title, fontsize=10)
    return save_figure(figure, path)


def failure_reasons_figure(path, summary: dict, *, title: str) -> Path:
    """Bar chart of the failed trials by failure kind (a trial counts once per kind)."""
    kinds = summary["failure_kinds"]
    figure = Figure(figsize=(7.2, 1.6 + 0.4 * max(len(kinds), 1)), layout="constrained")
    axis = figure.subplots()
    if kinds:
        labels = list(kinds)[::-1]
        axis.barh(labels, [kinds[label] for label in labels], color="tab:red")
        axis.set_xlabel(f"trials (of {summary['rows']})")
    else:
        axis.text(0.5, 0.5, f"no failures in {summary['rows']} trials", ha="center", va="center",
                  transform=axis.transAxes)
        axis.set_axis_off()
    axis.set_title(title, fontsize=10)
    return save_figure(figure, path)
