"""Q-learning: reproducibility, policy files, warm start, refinement, steadiness."""

import json

import numpy as np
import pytest

import drake_lfd.planning.mdp as mdp
import drake_lfd.planning.q_learning as mut
from drake_lfd.io.policy_files import POLICY_FORMAT_VERSION, load_policy, save_policy
from drake_lfd.core.errors import InputError
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.random_tasks import chained_task
from drake_lfd.core.synthetic_library import PAPER5, PAPER6, synthetic_features
from drake_lfd.planning.training import train_on_random_tasks


@pytest.fixture(scope="module")
def features():
    return synthetic_features(PAPER5)


@pytest.fixture(scope="module")
def trained(features):
    return train_on_random_tasks(features, num_tasks=10, num_chained_tasks=10, episodes=30, seed=4)


def test_training_is_seeded_and_reproducible(features, trained):
    again = train_on_random_tasks(features, num_tasks=10, num_chained_tasks=10, episodes=30, seed=4)
    assert again.policy.values == trained.policy.values
    np.testing.assert_array_equal(again.rewards, trained.rewards)
    other = train_on_random_tasks(features, num_tasks=10, num_chained_tasks=10, episodes=30, seed=5)
    assert other.policy.values != trained.policy.values


def test_learning_improves_the_average_reward(trained):
    curve = trained.curve
    assert curve.shape == (30,)
    assert curve[-10:].mean() > curve[:5].mean()


def test_policy_file_round_trip_and_warm_start(features, trained, tmp_path):
    path = tmp_path / "policy.json"
    save_policy(trained.policy, path)
    loaded = load_policy(path)
    assert loaded.values == pytest.approx(trained.policy.values)
    assert loaded.parameters == trained.policy.parameters
    assert json.loads(path.read_text())["format_version"] == POLICY_FORMAT_VERSION
    six = synthetic_features(PAPER6)
    warm = train_on_random_tasks(six, num_tasks=5, episodes=5, seed=1, warm_start=loaded)
    assert warm.policy.training_episodes == loaded.training_episodes + 5
    assert set(loaded.values) <= set(warm.policy.values)
    assert loaded.values == pytest.approx(trained.policy.values)  # the old table is untouched


@pytest.mark.parametrize("text, field", [
    ("{", "not a JSON policy"),
    ('{"format_version": 99, "values": {}}', "format_version"),
    ('{"format_version": 1, "values": {"a": "x"}, "parameters": {}, "library_demos": []}', "malformed"),
])
def test_bad_policy_files_are_input_errors(tmp_path, text, field):
    path = tmp_path / "p.json"
    path.write_text(text)
    with pytest.raises(InputError, match=field):
        load_policy(path)


def test_greedy_probability_is_saved_and_old_epsilon_files_still_load(trained, tmp_path):
    path = tmp_path / "policy.json"
    save_policy(trained.policy, path)
    document = json.loads(path.read_text())
    assert document["parameters"]["greedy_probability"] == 0.8 and "epsilon" not in document["parameters"]
    # A file written before the rename: epsilon meant the probability of the greedy action.
    parameters = dict(document["parameters"])
    parameters["epsilon"] = parameters.pop("greedy_probability")
    parameters["epsilon"] = 0.7
    document["parameters"] = parameters
    path.write_text(json.dumps(document))
    old = load_policy(path)
    assert old.parameters.greedy_probability == 0.7
    assert old.values == pytest.approx(trained.policy.values)


def test_greedy_probability_is_the_probability_of_the_greedy_action(features):
    # With probability 1 no action is random, so the seed does not matter; with 0.5 it does.
    problems = [build_problem(chained_task(np.random.default_rng(s), features)[0], features) for s in range(3)]

    def values(greedy_probability, seed):
        parameters = mut.QLearningParameters(greedy_probability=greedy_probability, episodes=10)
        return mut.train(problems, library_demos=list(features), parameters=parameters, seed=seed).policy.values

    assert values(1.0, 1) == values(1.0, 2)
    assert values(0.5, 1) != values(0.5, 2)


def test_planning_layer_writes_no_files():
    import ast
    import inspect

    for module in (mut, mdp):
        tree = ast.parse(inspect.getsource(module))
        imported = [node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
        imported += [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names]
        assert not [name for name in imported if name and name.startswith(("drake_lfd.io", "json", "pathlib"))]


def test_refined_greedy_walk_is_near_optimal_and_never_changes_the_policy(features, trained):
    rng = np.random.default_rng(77)
    before = dict(trained.policy.values)
    refined, optimal = [], []
    for _ in range(20):
        task, _ = chained_task(rng, features, perturbation_deg=15, perturbation_m=0.02)
        problem = build_problem(task, features)
        steps = mut.greedy_walk(problem, trained.policy, refine_episodes=100)
        assert steps is not None
        refined.append(sum(s.cost for s in steps))
        optimal.append(sum(s.cost for s in plan_exact(problem)))
    assert np.mean(refined) <= 1.05 * np.mean(optimal)
    assert trained.policy.values == before


def test_episodes_to_steady():
    curve = np.concatenate([np.linspace(-10, -1, 40), np.full(60, -1.0)])
    assert mut.episodes_to_steady(curve) == 38  # within 5 % of the range from episode 39 on
    step = np.concatenate([np.full(18, -10.0), np.full(82, -9.67)])
    assert mut.episodes_to_steady(step) == 18
    assert mut.episodes_to_steady(np.full(100, -2.0)) == 0


def test_plan_with_the_q_planner_refuses_a_library_beyond_its_limit(monkeypatch):
    """One line naming the exact planner (InputError: exit 2), before the policy is read."""
    import argparse

    from drake_lfd.cli import plan as plan_cli
    from drake_lfd.core.errors import InputError
    from drake_lfd.io.library import Library
    from drake_lfd.planning import q_learning

    library = Library.open("paper5")
    args = argparse.Namespace(planner="q", policy="no_such_policy.json", command="plan")
    monkeypatch.setattr(q_learning, "Q_PLANNER_MAX_DEMOS", 4)
    with pytest.raises(InputError) as error:
        plan_cli.load_policy_for(args, library)
    assert error.value.field == "--planner"
    assert "--planner exact" in str(error.value) and "at most 4 demonstrations" in str(error.value)
    assert "\n" not in str(error.value)
    monkeypatch.setattr(q_learning, "Q_PLANNER_MAX_DEMOS", 5)  # at the limit: on to the policy
    with pytest.raises(Exception) as error:
        plan_cli.load_policy_for(args, library)
    assert "no_such_policy.json" in str(error.value)
