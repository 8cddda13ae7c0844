"""Layer 6, Diagrams: the systems wired with the UR5e MultibodyPlant.

``station`` (the UR5e work cell, owning its plants), ``pipeline`` (library -> planner
-> trajectory -> diff IK -> station, monitor and logger), ``closed_loop`` (running trials
on one pipeline), ``kinesthetic`` (simulated kinesthetic demonstrations),
``model_preview`` (a Meshcat page of the arm).
"""
