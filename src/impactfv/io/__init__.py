"""Writers: ParaView (VTU + PVD), history CSV, summary JSON, checkpoints; every file written
atomically."""

from .writers import SnapshotWriter, atomic_write_text, write_history_csv, write_summary

__all__ = ["atomic_write_text", "write_history_csv", "write_summary", "SnapshotWriter"]
