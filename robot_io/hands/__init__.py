"""Hand sources, what a lab buys to track the participant's hand: the simulated participant, LSL,
UDP/JSON, OptiTrack's NatNet and Vicon's DataStream, the tracker → robot-base frame, and the hand
publisher of a rehearsal."""
