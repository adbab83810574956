"""The rig process: the control loop in a process of its own, owning the arm, the hand source and
the gripper (docs/controller.md, the rig process). :class:`~robot_io.rig.client.RigClient` starts
and talks to it."""
