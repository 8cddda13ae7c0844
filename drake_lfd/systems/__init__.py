"""Layer 5, the Drake LeafSystems, one per stage, thin wrappers over the layers below.

``demo_recorder.DemoRecorder`` -> ``feature_library.FeatureLibrarySystem`` ->
``planner.PlannerSystem`` -> ``plan_trajectory_source.PlanTrajectorySource`` ->
``differential_ik.DifferentialIKController``; ``shell_monitor.ShellMonitor`` watches
the scene; ``virtual_hand.VirtualHand`` guides the arm in a simulated demonstration.

Every abstract port carries a model value of its real type; importing this package
installs ``typed_ports.install_connect_check``, so ``DiagramBuilder.Connect`` refuses to
connect two abstract ports whose Python classes differ (Drake itself only compares C++
types, and every Python object is the one C++ type ``Value[object]``).
"""

from drake_lfd.systems.typed_ports import install_connect_check

install_connect_check()
