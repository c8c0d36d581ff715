"""Writers: ParaView (VTU + PVD), history CSV, summary JSON; every file written atomically."""

from .writers import atomic_write_text, write_history_csv, write_summary, SnapshotWriter

__all__ = ["atomic_write_text", "write_history_csv", "write_summary", "SnapshotWriter"]
