"""Training logs: ``metrics.jsonl`` and TensorBoard event files in the workdir.

``metrics.jsonl`` holds one JSON object per logged step with at least ``step``
and ``loss`` (training) or ``val_loss`` (validation), appended and flushed
line by line so that a crash loses nothing already logged. On resume, lines of
steps after the restored checkpoint are dropped, so the file stays a single
consistent history.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["MetricsWriter"]


class MetricsWriter:
    """Append scalar metrics to ``metrics.jsonl`` and TensorBoard (``tb/``) in ``workdir``."""

    def __init__(self, workdir, *, resume_step: int | None = None, tensorboard: bool = True):
        self.path = Path(workdir) / "metrics.jsonl"
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if resume_step is not None and self.path.exists():
            self._truncate_after(resume_step)
        elif resume_step is None and self.path.exists():
            self.path.unlink()
        self._file = open(self.path, "a", buffering=1)
        self._tb = None
        if tensorboard:
            try:
                from tensorboardX import SummaryWriter
            except ImportError:  # optional: the JSON log is the source of truth
                SummaryWriter = None
            if SummaryWriter is not None:
                self._tb = SummaryWriter(str(Path(workdir) / "tb"), flush_secs=10)

    def _truncate_after(self, step: int):
        keep = []
        for line in self.path.read_text().splitlines():
            try:
                if json.loads(line).get("step", 0) <= step:
                    keep.append(line)
            except json.JSONDecodeError:
                continue  # a line cut by a crash
        self.path.write_text("".join(line + "\n" for line in keep))

    def write(self, step: int, metrics: dict):
        row = {"step": int(step)}
        for k, v in metrics.items():
            v = float(v)
            row[k] = v if math.isfinite(v) else str(v)
        self._file.write(json.dumps(row) + "\n")
        if self._tb is not None:
            for k, v in row.items():
                if k != "step" and isinstance(v, float):
                    self._tb.add_scalar(k, v, step)

    def close(self):
        self._file.close()
        if self._tb is not None:
            self._tb.close()
