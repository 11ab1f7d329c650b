"""The sweep's progress bar (rich, on stderr): points done, failures, time left."""

from __future__ import annotations


class Progress:
    """Rich progress bar: points done, failures, time left (stderr)."""

    def __init__(self, total: int, done: int, failed: int, enabled: bool = True, console=None, *,
                 name: str = "sweep", unit: str = "points", groups: tuple[int, int, str] | None = None):  # fmt: skip
        """``total`` items (``unit``), ``done`` of them already; ``groups = (done, total, unit)``
        counts the jobs the items come in (a scan: pixels in lines)."""
        self.enabled = enabled and total > 0
        self.total, self.done0, self.failed = total, done, failed
        self.groups = list(groups) if groups else None
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

            group = [TextColumn("{task.fields[groups]}")] if groups else []
            self.progress = Progress(
                TextColumn(f"[bold]{name}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn(unit + ", {task.fields[failed]} failed"),
                *group,
                TimeElapsedColumn(),
                TextColumn("left"),
                TimeRemainingColumn(),
                console=console or Console(stderr=True),
            )
            self.task = self.progress.add_task(name, total=total, completed=done, failed=failed, groups=self._groups())

    def __enter__(self):
        if self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc):
        if self.progress is not None:
            self.progress.stop()
        return False

    def _groups(self) -> str:
        return f"| {self.groups[0]}/{self.groups[1]} {self.groups[2]}" if self.groups else ""

    def advance(self, n: int, failed: int, groups: int = 0) -> None:
        """``n`` more items done (``groups`` more jobs), ``failed`` items failed so far."""
        if self.groups:
            self.groups[0] += groups
        if self.progress is not None:
            self.progress.update(self.task, advance=n, failed=failed, groups=self._groups())
