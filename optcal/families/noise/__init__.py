"""Noise analysis of a still log: one Allan analysis for the accelerometer and the gyroscope."""
