"""Velma's controllers: Pinocchio model and index map, impedance laws, IK, setpoint paths,
hand control."""
