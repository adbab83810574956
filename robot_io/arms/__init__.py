"""Arms: the UR over RTDE (its worker and kinematics) and the kinematic mock arm."""
