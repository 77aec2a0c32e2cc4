"""What every ``optcal reproduce`` command shares on the command line: progress bars and the acceptance verdict."""

from __future__ import annotations

import click


def show_progress() -> bool:
    """Draw tqdm progress bars: the command line's one decision (:func:`optcal.core.progress.decide`: standard
    error a terminal, not ``--quiet``, not ``--json`` into a pipe; in a log file a bar becomes one long line)."""
    from optcal.core.progress import enabled

    return enabled()


def acceptance_lines(checks: dict[str, bool]) -> list[str]:
    """One plain line per acceptance check: ``[ok] check`` or ``[FAILED] check``."""
    return [f"  [{'ok' if met else 'FAILED'}] {check}" for check, met in checks.items()]


def exit_if_acceptance_failed(checks: dict[str, bool]) -> None:
    """One ``acceptance failed: ...`` line on standard error and exit code 1 when a check failed."""
    failed = [check for check, met in checks.items() if not met]
    if failed:
        click.echo("acceptance failed: " + "; ".join(failed), err=True)
        raise click.exceptions.Exit(1)
