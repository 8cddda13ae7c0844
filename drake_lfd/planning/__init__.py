"""Layer 3, planning: from a concrete task and a library's features to a composition.

``composition`` (legal actions from similarity), ``mdp`` (the one MDP: states,
actions, rewards, penalties), ``exact_planner`` (shortest path), ``q_learning``
(Algorithm 1 and 2), ``state_abstraction`` (the policy's task-independent key),
``training``, ``random_tasks``, ``gym_env`` (the MDP as a Gymnasium environment),
``options`` (the planning options, with the command line's defaults), ``planner``
(plan a task: compose, map, time), ``replanning`` (a plan on the
simulation clock, and replanning when the task changes).
"""
