"""The controller: the DMP and its coupling to the hand, the control loop, the handover cycle, the
safety limiter and the force-threshold release (docs/controller.md)."""
