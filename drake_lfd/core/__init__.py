"""Layer 1, the core: the paper's maths and data types, pure numpy (Drake math types allowed).

No Diagram, no file writes; every equation can be tested without building a system.
In the default pipeline the core supplies the features the library holds, the
similarity test and the mapping the planner uses, and the SE(3) timing law that times
the paper's baseline (``timing``).

The modules:

* ``dual_quaternion``: dual quaternions for rigid poses (Eq. 1-9), products,
  conversions, screw interpolation.
* ``features``: features of demonstrations and task segments (Eq. 12-18), arc-length
  resampling.
* ``similarity``: the similarity test of a segment and a demonstration (Eq. 19-21), the
  one allocation kernel.
* ``mapping``: a demonstration mapped onto a task segment (Eq. 22-25) and bent through
  its critical configurations.
* ``fidelity``: shape fidelity of a mapped demonstration, the allocation cost beyond
  Eq. 31.
* ``timing``: the UR5e's motion limits (``TimingLimits``) and the SE(3) timing law of a
  plan.
* ``tasks``: the task data model: critical configurations, boxes, path constraints,
  trials (Eq. 10).
* ``demonstrations``: the demonstration data type, a joint-angle time series (Eq. 11).
* ``tool``: the tool and what it holds, solids fixed to the flange frame ``tool0``.
* ``people``: people in the cell (capsule bodies on scripted paths or recorded tracks)
  and ISO/TS 15066's protective separation distance and speed override.
* ``guidance``: the guiding hand's path in a simulated kinesthetic demonstration.
* ``synthetic_library``: hand-built demonstrations with the motions of the paper's
  Fig. 5, as pose sequences.
* ``failures``: why a trial failed, as records of a closed set of kinds (each also its
  line), so summaries never parse text.
* ``errors``: errors users can act on (``InputError``) and the command line's exit
  codes.
* ``option_values``: the closed sets and defaults of user options (planners, costs,
  workers), plain Python for the command line.
* ``task_terms``: the closed sets and bounds a task is made of (path-constraint kinds,
  override policies, the fewest critical configurations), plain Python for the checks
  of a task file before Drake loads.
* ``resources``: where the shipped data lives (the UR5e model, the paper's scenarios).
* ``network_policy``: Drake's network switch, ``DRAKE_ALLOW_NETWORK``, read as Drake
  reads it.
* ``exact_memo``: a bounded, process-local memo keyed by exact inputs.
* ``read_only_arrays``: read-only numpy arrays for the frozen dataclasses passed between
  stages.
"""
