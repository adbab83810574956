"""Stand-ins for the lab's hardware, spoken to over real sockets: a UR controller (with the Robotiq
URCap's socket) and OptiTrack Motive's NatNet server."""
