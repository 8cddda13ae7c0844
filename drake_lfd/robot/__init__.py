"""Layer 2, the robot: the UR5e as a MultibodyPlant and what is computed on it.

``kinematics`` (forward kinematics of E, limits, FK of demonstrations), ``initial_ik``
(the first joint configuration, elbow up), ``scene`` (obstacles, shells and table as
geometry; signed distances).
"""
