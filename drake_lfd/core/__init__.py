"""Layer 1, the core: the paper's maths and data types, pure numpy (Drake math types allowed).

``dual_quaternion`` (Eq. 1-9), ``features`` (Eq. 12-18, arc-length resampling),
``similarity`` (Eq. 19-21, the one allocation kernel), ``mapping`` (Eq. 22-25),
``timing`` (the timing law), ``tasks`` and ``demonstrations`` (data types),
``errors``, ``resources`` (where shipped data lives), ``read_only_arrays``,
``guidance`` (guided paths for simulated demonstrations), ``synthetic_library``.
No Diagram, no file writes; every equation can be tested without building a system.
"""
