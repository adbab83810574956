"""The web app (viser): the participant's tablet and the experimenter's dashboard (issue 5)."""
