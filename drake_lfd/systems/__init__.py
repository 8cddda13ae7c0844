"""Layer 5, the Drake LeafSystems, one per stage, thin wrappers over the layers below.

``demo_recorder.DemoRecorder`` -> ``feature_library.FeatureLibrarySystem`` ->
``planner.PlannerSystem`` -> ``plan_trajectory_source.PlanTrajectorySource`` ->
``differential_ik.DifferentialIKController``; ``shell_monitor.ShellMonitor`` watches
the scene; ``virtual_hand.VirtualHand`` guides the arm in a simulated demonstration.
"""
