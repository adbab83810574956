"""The application layer (docs/controller.md, the rig process): the lab configuration, the running
session behind both screens and the headless command, the rig it drives, and the rehearsal rig."""
