"""The check before Drake loads finds what loading finds: same message, same order.

``io/task_checks.py`` checks a task file (and ``simulate --people``'s people file) in
plain Python: the structure, the loader's structure check with the typed blocks, the
values as Drake's loader makes them (``yaml_checks.plain_load``), then the value checks
the loader itself runs (one implementation, ``task_checks.check_task_values``). These
tests hold it to loading the file: the plain Spec equals Drake's, the ``simulation:``
block's plain keys mirror its config, and on seeded fuzzed files every refusal of the
early check is, word for word, the refusal of loading the file; where the early check
says it checked everything, the file loads.
"""

import collections
import dataclasses
import math
import typing
from pathlib import Path

import pytest

from drake_lfd.core.errors import InputError
from drake_lfd.io import simulation_config, simulation_schema
from drake_lfd.io.people_files import load_people_file
from drake_lfd.io.task_checks import precheck_people_file, precheck_task_file
from drake_lfd.io.task_files import TaskSpec, load_task, task_spec_from_text
from drake_lfd.io.task_schema import TypedTaskSpec, check_task_file, check_task_text
from drake_lfd.io.yaml_checks import plain_load
from fuzzing import default_task_bases, task_cases  # tests/fuzzing.py

# A task file with every block, each key given (no Drake struct, no body, no track).
RICH = """name: rich
description: every block
X_WB: {p: [-0.2, 0.7, 0.0], euler_zyx: [0, 0, 0]}
X_tool0_E: {p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}
angle_grid_deg: 15
variables: {z: [0.1, 0.5]}
critical_configurations:
  - {p: [-0.5, 0, 0.3], euler_zyx: [0, -pi/2, 0], stop: true}
  - {p: [-0.4, 0.2, z], euler_zyx: [0, -pi/2, [-90deg, 90deg]]}
  - {p: [[-0.1, 0.1], 0.2, z], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.1, 0, 0.3], euler_zyx: [0, -pi/2, 0]}
obstacles:
  - {name: obstacle, centre: [-0.3, -0.1, 0.2], size: [0.2, 0.2, 0.2], euler_zyx: [0.1, 0, 0]}
safety_shells:
  - {name: shell, centre: [-0.3, -0.1, 0.2], size: [0.4, 0.4, 0.4]}
path_constraints:
  - {kind: orientation, between: [1, 4], euler_zyx: [0, -pi/2, 0], tolerance_deg: 10,
     max_deviation: {position_m: 0.05, rotation_deg: 5}}
simulation:
  station: {time_step: 0.004, command_period: 0.01, model_name: ur5e, gravity_compensation: arm_weightless,
            visualizer_publish_period: 0.05, sampled_output_ports: false,
            drive: {gear_ratio: 101, proportional_gains: [4800, 4800, 3000, 300, 300, 300]}}
  controller: {method: compiled, time_step: 0.01, position_gain: 20.0, velocity_limit_fraction: 0.97}
  monitor: {period: 0.01, stop_on_penetration: false, from_log: true}
  planner: {check_period: 0.05}
  joint_check: {elbow_margin: 0.06, wrist_margin: 0.06, shoulder_margin_m: 0.05, clearance_m: 0.01}
  log_period: 0.01
  settle_s: 0.5
timing: {joint_speed_rad_s: 3, tool_acceleration_m_s2: 2.0, limit_fraction: 0.8}
refinement:
  max_deviation: {position_m: 0.1}
  spans: [{between: [2, 3], rotation_deg: 5}]
tool:
  - {name: holder, cylinder: {radius: 0.03, length: 0.15}, p: [0, 0, 0.075]}
  - {name: cup, box: [0.08, 0.08, 0.1], p: [0, 0, 0.2]}
people:
  - name: operator
    path: [{t: 0.0, xy: [-0.2, -2.0]}, {t: 1.5, xy: [-0.2, -0.75]}]
    reach: {toward: [0, 0, 0.3], t: [1.0, 2.0]}
collaboration: {policy: stop_only, stop_radius_m: 1.2, human_speed_m_s: 1.6}
"""
# Where the early check stops: a body's proportions, Drake's structs in the simulation block.
WITH_BODY = RICH.replace("    reach: {toward", "    body: {torso_radius_m: 0.25}\n    reach: {toward")
WITH_STRUCTS = RICH.replace("  station: {time_step: 0.004,",
                            "  simulator: {target_realtime_rate: 0.0}\n  station: {plant: {penetration_allowance: 0.001},")
PEOPLE = """people:
  - name: operator
    path: [{t: 0.0, xy: [-0.2, -2.0]}, {t: 1.5, xy: [-0.2, -0.75]}, {t: 4.0, xy: [-0.2, -0.75]}]
    reach: {toward: [0, 0, 0.3], t: [1.0, 2.0]}
  - name: visitor
    path: [{t: 0.5, xy: [1.0, -2.0]}]
collaboration: {human_speed_m_s: 1.6, reaction_time_s: 0.1, intrusion_distance_m: 0.2, floor_z_m: -0.75}
"""


def _outcome(run):
    try:
        return run()
    except InputError as error:
        return "refused", str(error)


def _compare(early, loading):
    """How the early check's outcome relates to loading's; "differ" must never happen."""
    if early == "complete":
        return "complete" if loading == "loaded" else "differ"
    if early == "stopped":
        return "stopped"
    return "same refusal" if early == loading else "differ"


def test_the_simulation_block_keys_mirror_its_config():
    """The same keys in the same order (error messages list them), the same kinds of
    values, Drake's structs where DRAKE_STRUCT_KEYS says."""
    pairs = [(simulation_schema.SimulationSpec, simulation_config.PipelineConfig, ""),
             (simulation_schema.StationSpec, simulation_config.StationConfig, "station"),
             (simulation_schema.DriveSpec, simulation_config.DriveConfig, "station.drive"),
             (simulation_schema.ControllerSpec, simulation_config.ControllerConfig, "controller"),
             (simulation_schema.MonitorSpec, simulation_config.MonitorConfig, "monitor"),
             (simulation_schema.PlannerSystemSpec, simulation_config.PlannerSystemConfig, "planner"),
             (simulation_schema.JointCheckSpec, simulation_config.JointCheckConfig, "joint_check")]
    nested = {spec: config for spec, config, _ in pairs}
    for spec, config, block in pairs:
        assert [f.name for f in dataclasses.fields(spec)] == [f.name for f in dataclasses.fields(config)], spec
        spec_hints, config_hints = typing.get_type_hints(spec), typing.get_type_hints(config)
        for name, hint in spec_hints.items():
            if name in simulation_schema.DRAKE_STRUCT_KEYS.get(block, ()):
                assert hasattr(config_hints[name], "__fields__"), (block, name)  # one of Drake's structs
            elif dataclasses.is_dataclass(hint):
                assert nested[hint] is config_hints[name], (block, name)
            else:
                assert hint == config_hints[name], (block, name)


@pytest.mark.parametrize("text", [RICH, *default_task_bases().values()], ids=["rich", *default_task_bases()])
def test_plain_load_makes_the_spec_drake_loads(text):
    raw = check_task_text(text)
    plain, loaded = plain_load(raw, TypedTaskSpec), task_spec_from_text(text)
    for field in dataclasses.fields(TypedTaskSpec):
        if field.name != "simulation":
            assert getattr(plain, field.name) == getattr(loaded, field.name), field.name
    # The simulation block's given values, as the config holds them (None: its default).
    for block in ("station", "controller", "monitor", "planner", "joint_check"):
        given = getattr(plain.simulation, block)
        for key in (f.name for f in dataclasses.fields(given) if f.name not in ("drive", "plant", "visualization")):
            value = getattr(given, key)
            assert value is None or value == getattr(getattr(loaded.simulation, block), key), (block, key)
    assert plain.simulation.station.drive.proportional_gains in (None, loaded.simulation.station.drive.proportional_gains)
    assert plain.simulation.settle_s in (None, loaded.simulation.settle_s)
    assert isinstance(TaskSpec(), TypedTaskSpec)


def test_the_rich_file_is_checked_whole_and_the_others_stop_where_drake_must_judge(tmp_path):
    for text, whole in ((RICH, True), (WITH_BODY, False), (WITH_STRUCTS, False)):
        path = tmp_path / "task.yaml"
        path.write_text(text)
        assert precheck_task_file(path) is whole
        load_task(path)
    path = tmp_path / "people.yaml"
    path.write_text(PEOPLE)
    assert precheck_people_file(path) is True
    load_people_file(path)


@pytest.mark.parametrize(("change", "field"), [
    (("[-0.5, 0, 0.3]", "[-0.5, .nan, 0.3]"), "critical_configurations[0].p[1]"),
    (("[-90deg, 90deg]", "[90deg, -90deg]"), "critical_configurations[1].euler_zyx[2]"),
    (("clearance_m: 0.01", "clearance_m: -0.01"), "simulation.joint_check.clearance_m"),
    (("settle_s: 0.5", "settle_s: .inf"), "simulation.settle_s"),
    (("method: compiled", "method: pid"), "simulation.controller.method"),
    (("limit_fraction: 0.8", "limit_fraction: 1.5"), "timing.limit_fraction"),
    (("t: [1.0, 2.0]", "t: [2.0, 1.0]"), "people[0].reach.t"),
    (("policy: stop_only", "policy: wait"), "collaboration.policy"),
    (("rotation_deg: 5}]", "rotation_deg: 500}]"), "refinement.spans[0].rotation_deg"),
    (("radius: 0.03", "radius: -0.03"), "tool[0].cylinder.radius"),
    (("size: [0.4, 0.4, 0.4]", "size: [0.4, 0, 0.4]"), "safety_shells[0].size[1]"),
])
def test_a_value_out_of_range_is_refused_early_as_loading_refuses_it(tmp_path, change, field):
    path = tmp_path / "task.yaml"
    assert change[0] in RICH
    path.write_text(RICH.replace(*change))
    with pytest.raises(InputError) as early:
        precheck_task_file(path)
    with pytest.raises(InputError) as loading:
        load_task(path)
    assert str(early.value) == str(loading.value)
    assert early.value.field == field


def test_a_task_file_with_a_collaboration_block_passes_the_structure_check(tmp_path):
    """Was refused by the command line's structure check ("expected a mapping of
    collaboration keys ..., got a mapping"), while loading it worked."""
    path = tmp_path / "task.yaml"
    path.write_text(RICH)
    check_task_file(path)


def _fuzz_outcomes(bases, count, seed, tmp_path, early_check, load):
    kinds = collections.Counter()
    path = tmp_path / "fuzzed.yaml"
    for case in task_cases(count, seed=seed, bases=bases):
        path.write_bytes(case.data)
        early = _outcome(lambda: "complete" if early_check(path) else "stopped")
        loading = _outcome(lambda: load(path) and "loaded")
        kind = _compare(early, loading)
        assert kind != "differ", (case.mutation, early, loading)
        kinds[kind] += 1
    return kinds


@pytest.mark.slow
def test_on_fuzzed_task_files_the_early_check_refuses_as_loading_does(tmp_path):
    """240 seeded fuzzed files (the shipped scenarios, the rich file and the two that
    stop): no difference, and each outcome occurs (refusals, whole checks, stops)."""
    bases = {**default_task_bases(), "rich": RICH, "with_body": WITH_BODY, "with_structs": WITH_STRUCTS}
    kinds = _fuzz_outcomes(bases, 240, 0, tmp_path, precheck_task_file,
                           lambda path: (check_task_file(path), load_task(path)))
    assert kinds["same refusal"] > 100 and kinds["complete"] > 10 and kinds["stopped"] > 10, kinds


def test_on_fuzzed_people_files_the_early_check_refuses_as_loading_does(tmp_path):
    kinds = _fuzz_outcomes({"people": PEOPLE}, 120, 0, tmp_path, precheck_people_file, load_people_file)
    assert kinds["same refusal"] > 50 and kinds["complete"] > 5, kinds


def test_nothing_in_the_early_check_is_a_number_drake_reads_otherwise():
    """The plain loader converts as Drake's does: an integer into a float field, a
    number-like string into a float field, a whole float into an integer field."""
    raw = check_task_text(RICH.replace("angle_grid_deg: 15", "angle_grid_deg: 1e1").replace(
        "between: [1, 4]", "between: [1.0, 4]"))
    spec = plain_load(raw, TypedTaskSpec)
    assert spec.angle_grid_deg == 10.0 and isinstance(spec.angle_grid_deg, float)
    assert spec.path_constraints[0].between == [1, 4] and all(isinstance(v, int) for v in spec.path_constraints[0].between)
    assert spec.timing.joint_speed_rad_s == 3.0 and isinstance(spec.timing.joint_speed_rad_s, float)
    assert spec.critical_configurations[1].euler_zyx[2] == ["-90deg", "90deg"]
    assert math.isclose(spec.X_tool0_E.p[2], 0.2)
