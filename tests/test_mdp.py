"""The composition MDP: the paper's action set, transitions, rewards and penalty."""

import numpy as np
import pytest

import drake_lfd.planning.mdp as mut
from drake_lfd.core.synthetic_library import PAPER5, synthetic_features
from drake_lfd.planning.composition import Step
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.random_tasks import chained_task, random_training_task
from drake_lfd.planning.state_abstraction import state_key


@pytest.fixture(scope="module")
def features():
    return synthetic_features(PAPER5)


@pytest.fixture(scope="module")
def problems(features):
    rng = np.random.default_rng(4)
    return [build_problem(make(rng), features, max_span=2)
            for make in (lambda r: chained_task(r, features, num_cons=5)[0], random_training_task)]


def test_action_set_is_every_demo_and_span_legal_or_not(problems):
    for problem in problems:
        dut = mut.CompositionMDP(problem)
        for j in range(problem.num_cons - 1):
            for a in range(problem.num_candidates[j]):
                state = mut.State(j, a)
                legal, illegal = dut.legal_actions(state), dut.illegal_actions(state)
                last = min(problem.num_cons - 1, j + problem.max_span)
                pairs = {(d, k) for d in range(problem.num_demos) for k in range(j + 1, last + 1)}
                legal_pairs = {(s.demo, s.k) for s in legal}
                assert legal_pairs | {(x.demo, x.k) for x in illegal} == pairs
                assert not legal_pairs & {(x.demo, x.k) for x in illegal}
                # Legality is the composition problem's.
                for s in legal:
                    assert s.cost == problem.cost[(j, s.k, s.demo)][a, s.a_k]
                assert dut.actions(state) == [*legal, *illegal]
                assert dut.is_dead_end(state) == (not legal)


def test_transitions_rewards_and_the_scaled_penalty(problems):
    problem = problems[0]
    dut = mut.CompositionMDP(problem, base_penalty=-8.0)
    n = problem.num_cons
    assert [dut.penalty(j) for j in range(n)] == pytest.approx([-8.0 * (n - 1 - j) / (n - 1) for j in range(n)])
    state = dut.start_states()[0]
    while not dut.is_goal(state):
        legal = dut.legal_actions(state)
        assert legal, "a chained task is plannable from its first candidate"
        step = min(legal, key=lambda s: s.cost)
        transition = dut.step(state, step)
        assert transition == mut.Transition(mut.State(step.k, step.a_k), -step.cost, step.k == n - 1, True)
        if dut.illegal_actions(state):
            bad = dut.illegal_actions(state)[0]
            assert dut.step(state, bad) == mut.Transition(state, dut.penalty(state.j), True, False)
        state = transition.state
    with pytest.raises(ValueError):
        dut.step(mut.State(0, 0), Step(0, 1, 2, 0, 0, 0.0))


def test_action_for_takes_the_least_cost_candidate(problems):
    problem = problems[0]
    dut = mut.CompositionMDP(problem)
    for (j, k, d), matrix in problem.cost.items():
        if j != 0:
            continue
        action = dut.action_for(mut.State(0, 0), d, k)
        if np.isfinite(matrix[0]).any():
            assert (action.demo, action.k, action.a_k) == (d, k, int(np.argmin(matrix[0])))
    assert isinstance(dut.action_for(mut.State(0, 0), 0, problem.num_cons), mut.IllegalAction)


def test_state_keys_are_memoised_by_the_mdp_not_the_problem(problems):
    problem = problems[1]
    before = dict(vars(problem))
    dut = mut.CompositionMDP(problem)
    for j in range(problem.num_cons):
        assert dut.state_key(mut.State(j, 0)) == state_key(problem, j, 0)
    assert dut.state_key((1, 0)) is dut.state_key(mut.State(1, 0))
    assert vars(problem).keys() == before.keys()
