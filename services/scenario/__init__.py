"""Scenarios: scripted sessions of a person with the Robot Companion (several commands,
urgent interruptions, a moved object, an agent restart), run headless against the fleet and
checked against what they expect. ``roco scenario FILE`` runs one; the library below ships
the scenarios of the test suite."""
