"""drake-lfd: compose kinesthetic demonstrations into UR5e motion plans, on Drake.

Implements (and extends) Yu & Chang, "Reinforcement Learning Based User-Guided Motion
Planning for Human-Robot Collaboration". The pipeline, and the module holding each arrow:

    joint log (RTDE CSV) --read/validate-->  demonstration      demonstrations.py
    joint samples --UR5e FK-->               poses X_WE          kinematics.py
    poses --Eq. 7-->                         dual quaternions    dual_quaternion.py
    dual quaternions --Eq. 12, resample-->   feature HD_k        features.py
    features --store-->                      library LB          library.py
    task YAML --load/validate-->             critical configs    tasks.py
    task + LB --Eq. 19-21-->                 legal actions       similarity.py
    legal actions --Q-learning / exact-->    composition         planning modules
    composition --Eq. 22-25-->               SE(3) plan          mapping.py
    SE(3) plan --timing law-->               X_WE(t), V_WE(t)    trajectory modules
    X_WE(t) --differential IK-->             UR5e joint motion   closed-loop systems

Conventions (see README): metres, radians, seconds; quaternions (w, x, y, z); task
orientations ``euler_zyx: [yaw, pitch, roll]`` with R = Rz(yaw) Ry(pitch) Rx(roll).
"""

__version__ = "0.1.0"
