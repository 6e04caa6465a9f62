"""Episode records: the MCAP schema, writer and reader (including reading a truncated file)
(docs/records.md; the Rerun replay of the files is :mod:`pipeline.replay`, docs/replay.md).

``records`` imports nothing from ``world``, ``fewshot`` or ``rl``: the writer takes plain numpy
arrays and dicts through the episode-sink protocol of ``pipeline/rl/sink.py``.
"""

from .reader import FileMeta, Records, RecordsError, RecordsWarning, find_record_files, read_records
from .schema import log_time_ns, split_log_time
from .writer import RecordWriter

__all__ = [
    "FileMeta",
    "RecordWriter",
    "Records",
    "RecordsError",
    "RecordsWarning",
    "find_record_files",
    "log_time_ns",
    "read_records",
    "split_log_time",
]
