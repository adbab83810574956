"""Grippers: a UR tool digital output and a Robotiq 2F-85 on its URCap's socket."""
