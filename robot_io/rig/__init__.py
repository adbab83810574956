"""The rig process: the control loop in a process of its own, owning the arm, the hand source and
the gripper (DESIGN.md §1). :class:`~robot_io.rig.client.RigClient` starts and talks to it."""
