"""The application layer (DESIGN.md §1): the lab configuration, the running session behind both
screens and the headless command, the rig it drives, and the rehearsal rig."""
