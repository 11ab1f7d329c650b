"""A batch's progress bar (rich, on stderr): items done, failures, time left.

Until the first job of this run has finished, rich has no speed to measure, so the time
left shown is the caller's cost-model estimate (``estimate_s``, marked ``~``); a line
printed before the bar (``notice``) says what a silent start is (numba compiling its
kernels on a first run), and while it lasts -- until the first job has finished -- the
bar says ``compiling`` instead of counting the estimate down."""

from __future__ import annotations

import time

from ..checks import duration  # noqa: F401  (re-exported: where the estimates format a time)


def _estimate_column(progress_mod, bar):
    """A rich column: rich's measured time left once a job of this run has finished, the
    cost model's estimate (``~m:ss``) before."""

    class Column(progress_mod.TimeRemainingColumn):
        def render(self, task):
            from rich.text import Text

            if task.completed == bar.done0 and bar.notice:  # the kernels compile before the first job ends
                return Text("compiling", style="progress.remaining")
            if task.completed > bar.done0 or bar.estimate_s is None:
                return super().render(task)

            left = max(0.0, bar.estimate_s - (time.monotonic() - bar.t0))
            m, s = divmod(int(round(left)), 60)
            h, m = divmod(m, 60)
            text = f"~{h}:{m:02d}:{s:02d}" if h else f"~{m}:{s:02d}"
            return Text(text, style="progress.remaining")

    return Column()


class Progress:
    """Rich progress bar: items done, failures, time left (stderr)."""

    def __init__(self, total: int, done: int, failed: int, enabled: bool = True, console=None, *,
                 name: str = "sweep", unit: str = "points", groups: tuple[int, int, str] | None = None,
                 estimate_s: float | None = None, notice: str | None = None):  # fmt: skip
        """``total`` items (``unit``), ``done`` of them already; ``groups = (done, total, unit)``
        counts the jobs the items come in (a scan: pixels in lines); ``estimate_s``: the cost
        model's wall seconds for the rest, shown until a job has finished; ``notice``: a line
        printed when the bar starts."""
        self.enabled = enabled and total > 0
        self.total, self.done0, self.failed = total, done, failed
        self.estimate_s, self.notice, self.t0 = estimate_s, notice, time.monotonic()
        self.groups = list(groups) if groups else None
        self.progress = None
        if self.enabled:
            from rich import progress as progress_mod
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
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
                _estimate_column(progress_mod, self),
                console=console or Console(stderr=True),
            )
            self.task = self.progress.add_task(name, total=total, completed=done, failed=failed, groups=self._groups())

    def __enter__(self):
        self.t0 = time.monotonic()
        if self.progress is not None:
            if self.notice:
                self.progress.console.print(self.notice)
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
