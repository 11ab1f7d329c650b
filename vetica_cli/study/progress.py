"""The sweep's progress bar (rich, on stderr): points done, failures, time left."""

from __future__ import annotations


class Progress:
    """Rich progress bar: points done, failures, time left (stderr)."""

    def __init__(self, total: int, done: int, failed: int, enabled: bool = True, console=None, label: str = "sweep",
                 unit: str = "points"):  # fmt: skip
        self.enabled = enabled and total > 0
        self.total, self.done0, self.failed = total, done, failed
        self.progress = None
        if self.enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(
                TextColumn(f"[bold]{label}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn(unit + ", {task.fields[failed]} failed"),
                TimeElapsedColumn(),
                TextColumn("left"),
                TimeRemainingColumn(),
                console=console or Console(stderr=True),
            )
            self.task = self.progress.add_task(label, total=total, completed=done, failed=failed)

    def __enter__(self):
        if self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc):
        if self.progress is not None:
            self.progress.stop()
        return False

    def advance(self, n: int, failed: int) -> None:
        if self.progress is not None:
            self.progress.update(self.task, advance=n, failed=failed)
