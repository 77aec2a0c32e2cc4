"""Library messages in the command line's words.

Library messages name Python arguments (``allow_degenerate=True``); on the command line the
same advice reads as a flag (``--allow-degenerate``).  :func:`cli_message` applies the
command's own table (:data:`COMMAND_SPELLING`), then :data:`CLI_SPELLING`, to every ``error:``,
``warning:`` and ``note:`` line a command prints.
"""

from __future__ import annotations

import re

#: How a library message's Python wording reads on the command line: regular expression ->
#: replacement, applied in order after the command's own table (:data:`COMMAND_SPELLING`).
#: IPOPT's advice when it stops early (optcal.families.accel.mle.IPOPT_REMEDY), which names Python arguments.
IPOPT_ADVICE = re.escape("raise the iteration limit (ipopt_options={'ipopt.max_iter': 1000}) or start from another fit (init=...)")
CLI_SPELLING: dict[str, str] = {
    # the command line sets no IPOPT options
    IPOPT_ADVICE:
        "on the command line, try --method convex (the convex fit alone, no IPOPT) or add poses in orientations "
        "not yet covered",
    re.escape('check ipopt_options, or use method="convex"'): "use --method convex",
    re.escape("raise the solver's iteration limit (solver_options) or try solver='SCS'"): "try --method mle",
    re.escape("pass a larger max_iter or a looser tol"): "use --method default instead",
    re.escape('method="convex"'): "--method convex",
    re.escape("solver_options={'max_iter': 1000}"): "--solver-option max_iter=1000",
    r"\bsolver=\.\.\.": "--solver NAME",
    r"\bcheck (ipopt|solver)_options\b": "check --solver-option",
    re.escape("allow_degenerate=True"): "--allow-degenerate",
    re.escape("scale_range=(low, high)"): "--scale-range LOW HIGH",
    r'\bunits="([^"]*)"': r"--units \1",
    r'\bcolumns="([^"]*)"': r"--columns \1",
    r"\bcolumns=": "--columns",
    r"\btime_unit\b": "--time-unit",
    r"\bcounts_per_g\b": "--counts-per-g",
    r"\bcounts_zero=(\S+)": r"--counts-zero \1",
    r"\bcounts_per_dps\b": "--counts-per-dps",
    r"\bgyro_device_id=N\b": "--gyro-device-id N",
    r"\bgyro_device_id\b": "--gyro-device-id",
    r"\bdevice_id=N\b": "--device-id N",
    r"\bvehicle_id=N\b": "--vehicle-id N",
    r"\binstance must be\b": "--instance must be",
    r"\bgyro_counts_per_rad_s\b": "--gyro-counts-per-rad-s",
    r"\bgyro_counts_zero=VALUE": "--gyro-counts-zero VALUE",
    r"\bgyro_counts_zero\b": "--gyro-counts-zero",
    r"\ballan=": "--allan FILE",
    re.escape("random_walk_bound=True"): "--random-walk-bound",
    r"\bmax_loss_g( =)?": "--max-loss",
    r"\baccept_gyro_fit(=True)?": "--accept-gyro-fit",
    r"\bgyro_units=": "--gyro-units",
    r"\brate= or the time column": "--rate or the time column",
    r"\bg_sensitivity=True": "--g-sensitivity",
}

#: Per command: wording that reads differently there (the same Python argument, another flag).
COMMAND_SPELLING: dict[str, dict[str, str]] = {
    "apply": {r'\bunits="([^"]*)"': r"--data-units \1"},  # apply's --units is the output unit
    "export": {r' \(or pass units="[^"]*" if that is what it is\)': ""},  # export reads --poses in their own units
    "reproduce": {IPOPT_ADVICE: "the reproduction keeps that fit and reports it"},  # its fits are fixed by the paper
}


def cli_message(message: str, command: str | None = None) -> str:
    """A library message with the command line's flags in place of Python arguments.

    Parameters
    ----------
    message : str
        The library's message (Python wording).
    command : str, optional
        The optcal command that ran (``"apply"``); its :data:`COMMAND_SPELLING` is applied first.
    """
    for pattern, flag in (*COMMAND_SPELLING.get(command or "", {}).items(), *CLI_SPELLING.items()):
        message = re.sub(pattern, flag, message)
    return message


#: The optional extra that installs each optional import (pyproject.toml's optional-dependencies).
EXTRAS: dict[str, str] = {
    "dask": "fleet", "distributed": "fleet", "pyarrow": "parquet", "rosbags": "ros", "pyulog": "px4", "h5py": "hdf5",
    "mkdocs": "docs", "mkdocstrings": "docs", "mkdocs_click": "docs",
}


def missing_extra_message(exc: ImportError, command: str | None) -> str | None:
    """The one line for an optional package that is not installed, with the ``pip install`` that fixes it.

    Parameters
    ----------
    exc : ImportError
        Raised by an import of an optional package (its ``name`` names the module).
    command : str or None
        The optcal command that needed it.

    Returns
    -------
    str or None
        ``None`` when the module is not one of an extra's (a broken installation: the error goes on).
    """
    module = (exc.name or "").split(".")[0]
    extra = EXTRAS.get(module)
    if extra is None:
        return None
    who = f"optcal {command}" if command else "optcal"
    return f"{who} needs the {module} package, which is not installed: pip install 'optcal[{extra}]'"
