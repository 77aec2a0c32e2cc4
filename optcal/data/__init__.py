"""Measured data in: pose tables and raw recordings, readers, units and static detection."""

from optcal.data.tables import load_pose_table, read_csv_frame

__all__ = ["load_pose_table", "read_csv_frame", "load"]


def load(path, **kwargs):
    """Load DATA (a pose table, or later a raw recording) as a :class:`~optcal.poses.PoseTable`.

    This is the one entry point every command uses for DATA.
    """
    return load_pose_table(path, **kwargs)
