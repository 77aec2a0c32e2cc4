"""Running the command line in-process in tests."""

from __future__ import annotations

from optcal.cli.main import main


def run(argv, capsys) -> tuple[int, str, str]:
    """``optcal ARGV`` (each argument given as str) → (exit code, stdout, stderr)."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def run_args(capsys, *args: str) -> tuple[int, str, str]:
    """``optcal ARGS`` → (exit code, stdout, stderr), the arguments given one by one."""
    return run(list(args), capsys)
