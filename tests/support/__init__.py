"""Helpers shared by the test packages (browser driving, sessions)."""
