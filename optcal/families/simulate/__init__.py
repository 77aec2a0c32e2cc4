"""Simulated pose tables and recordings with known truth (one kinematics engine)."""
