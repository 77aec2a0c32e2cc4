"""Helpers shared by the tests: CLI runner and diagnosis cases."""
