"""Runners: how a job runs over a batch of items (`Runner`), and the simplest one, in this
process (`LocalRunner`). The fork-server pool is `vistac.fork_pool`, Ray tasks
`vistac.engine.RayRunner`; `vistac.engine` gathers them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any


# ------------------------------------------------------------------------------- runners
class Runner:
    """Runs a job over a batch of items (see the module's docstring).

    Attributes:
        concurrency: Jobs at once.
        returned_errors: Exception types that a job raises as a result (a failed trial,
            say): they are yielded in place of the result instead of ending the batch.
    """

    concurrency: int = 1
    returned_errors: tuple[type[BaseException], ...] = ()

    def run(self, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        """(position in `items`, result) of every item, in the order they finish."""
        raise NotImplementedError

    def map(self, items: Iterable[Any]) -> list[Any]:
        """The results of every item, in the order of `items`."""
        return list(self.ordered(items))

    __call__ = map

    def ordered(self, items: Iterable[Any]) -> Iterator[Any]:
        """The results in the order of `items`, each as soon as it and those before it are
        done (a progress bar can follow them)."""
        waiting: dict[int, Any] = {}
        next_position = 0
        runs = self.run(items)
        try:
            for position, result in runs:
                waiting[position] = result
                while next_position in waiting:
                    yield waiting.pop(next_position)
                    next_position += 1
        finally:
            runs.close()


def close_job(job: Any) -> None:
    """Close a job's per-process state, if it has any (its ``close()``)."""
    close = getattr(job, "close", None)
    if callable(close):
        close()


class LocalRunner(Runner):
    """Runs the items one after the other in this process.

    Args:
        job: Item -> result.
        returned_errors: Exception types a job raises as its result (yielded in its place);
            any other exception propagates.
    """

    def __init__(self, job: Callable[[Any], Any],
                 returned_errors: tuple[type[BaseException], ...] = ()):
        self.job, self.returned_errors = job, tuple(returned_errors)

    def run(self, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        """(position, result) of each item, in order (items are drawn one at a time)."""
        try:
            for position, item in enumerate(items):
                try:
                    result = self.job(item)
                except self.returned_errors as exc:
                    result = exc
                yield position, result
        finally:
            close_job(self.job)
