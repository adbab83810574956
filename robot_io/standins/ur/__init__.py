"""A stand-in UR controller for tests and dry runs: the controller's real protocols on a loopback address.

It speaks RTDE (port 30004), the dashboard server (29999) and the script ports (30001–30003) well enough
for ``ur_rtde``'s real ``RTDEControlInterface``, ``RTDEReceiveInterface``, ``RTDEIOInterface`` and
``DashboardClient`` to connect, upload their control script, stream ``servoL``, read the TCP pose and
force, set tool outputs and hit the watchdog. It interprets no URScript: it recognises the uploaded
``rtde_control`` program and runs a Python model of that program's register handshake. The arm is a
bounded first-order follower of servo targets — a protocol-level model, not robot dynamics. It also
answers a Robotiq URCap's gripper socket (port 63352) for a modelled 2F-85
(:mod:`robot_io.standins.urcap`).

Run it in its own process (``python -m robot_io.standins.ur --host 127.0.0.5``): ``ur_rtde``'s
constructors hold the GIL while they wait for the controller, so a stand-in in the same process
deadlocks. Tests inject faults (protective stop, dropped sockets, stalls) and read what the controller
received through a JSON-lines control port (:mod:`robot_io.standins.ur.control`).
"""
