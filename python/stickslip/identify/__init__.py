"""Identification of a real arm from its torque logs (docs/calibration.md, "Real arms"):
the regressor's base parameters, physically consistent estimates, the model written back,
held-out torques predicted, and excitation design. One stage per module."""
