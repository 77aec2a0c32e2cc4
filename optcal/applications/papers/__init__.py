"""Reproductions of the source papers (``optcal reproduce NAME``).

Each module exposes ``run(...) -> dict`` (JSON-safe) and a click command ``command``
registered in :data:`optcal.cli.cmd_reproduce.REPRODUCTIONS`.
"""
