"""The Gymnasium environment passes the conformance check and runs the MDP of ``mdp.py``."""

import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

import drake_lfd.planning.gym_env as mut  # noqa: E402
from drake_lfd.planning.exact_planner import plan_exact  # noqa: E402
from drake_lfd.core.synthetic_library import PAPER5, synthetic_features  # noqa: E402


@pytest.fixture(scope="module")
def features():
    return synthetic_features(PAPER5)


def test_check_env(features):
    check_env(mut.CompositionEnv(features), skip_render_check=True)


def test_following_the_exact_plan_earns_its_cost(features):
    env = mut.CompositionEnv(features)
    completed = 0
    for seed in range(10):
        env.reset(seed=seed)
        steps = plan_exact(env.problem)
        if steps is None or steps[0].a_j != 0:
            continue
        total, done = 0.0, False
        for step in steps:
            _, reward, done, _, info = env.step(step.demo * env.max_span + (step.k - step.j - 1))
            assert info["legal"]
            total += reward
        assert done
        assert total == pytest.approx(-sum(s.cost for s in steps), abs=1e-6)
        completed += 1
    assert completed >= 3


def test_illegal_action_ends_the_episode_with_the_mdps_penalty(features):
    env = mut.CompositionEnv(features)
    env.reset(seed=0)
    legal_spans = {(d, k) for (j, k, d) in env.problem.cost if j == 0}
    illegal = next(a for a in range(env.action_space.n)
                   if (a // env.max_span, a % env.max_span + 1) not in legal_spans)
    _, reward, terminated, _, info = env.step(illegal)
    assert terminated and reward == env.illegal_penalty == env.mdp.penalty(0) and not info["legal"]


def test_penalty_later_in_the_task_is_scaled_as_in_q_learning(features):
    # After one legal step the penalty is the MDP's: the base scaled by the task left.
    env = mut.CompositionEnv(features)
    for seed in range(20):
        env.reset(seed=seed)
        steps = plan_exact(env.problem)
        if steps is None or steps[0].a_j != 0 or steps[0].k == env.problem.num_cons - 1:
            continue
        first = steps[0]
        env.step(first.demo * env.max_span + (first.k - first.j - 1))
        j = env.state.j
        legal = {(s.demo, s.k) for s in env.mdp.legal_actions(env.state)}
        illegal = [a for a in range(env.action_space.n)
                   if (a // env.max_span, j + a % env.max_span + 1) not in legal]
        if not illegal:
            continue
        _, reward, terminated, _, info = env.step(illegal[0])
        n = env.problem.num_cons
        assert terminated and not info["legal"]
        assert reward == pytest.approx(env.illegal_penalty * (n - 1 - j) / (n - 1))
        assert reward == env.mdp.penalty(j) and reward > env.illegal_penalty
        return
    pytest.fail("no task with an illegal action after a first legal step")
