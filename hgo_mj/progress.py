"""Progress of long jobs on stderr, the one helper every job uses.

On a terminal a :mod:`tqdm` bar (done / total, rate, elapsed, ETA); otherwise (a log file, a
pipe, CI) a line at every tenth of the work, so a log stays short; nothing at all when
``quiet``. Studies (:class:`hgo_mj.study.Study`), ``hgo-mj run --seeds``, the reproductions
(``hgo-mj reproduce``) and the comparison scripts report through :class:`Progress` or
:func:`track`; each takes ``quiet`` (the command line's ``--quiet``).

Examples
--------
>>> lines = []
>>> with Progress(4, unit="part", desc="demo", echo=lines.append) as p:
...     for _ in range(4):
...         p.add()
>>> lines[-1].startswith("demo: 100% 4/4 parts")
True
>>> [x for x in track(range(3), quiet=True)]
[0, 1, 2]
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, TypeVar

T = TypeVar("T")


def seconds(s: float) -> str:
    """A duration for people: ``"12 s"``, ``"3.5 min"``, ``"1.2 h"`` (at least ``"1 s"``).

    Parameters
    ----------
    s : float
        A duration in seconds.

    Returns
    -------
    str
        Whole seconds below a minute, minutes with one decimal below an hour, else hours.

    Examples
    --------
    >>> [seconds(v) for v in (0.2, 12.4, 90.0, 7200.0)]
    ['1 s', '12 s', '1.5 min', '2.0 h']
    """
    if s < 60:
        return f"{s:.0f} s" if s >= 1 else "1 s"
    if s < 3600:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.1f} h"


class Progress:
    """Work done out of ``total`` units, on stderr: a tqdm bar with rate and ETA on a terminal,
    else a line at every tenth of the work (``echo``, default a line on stderr); nothing when
    ``quiet`` (or when there is no work).

    Parameters
    ----------
    total : int
        Units of work (runs, parts, cases).
    unit : str
        What one unit is called (``"run"``: lines say ``"runs"``).
    desc : str
        Prefix of the bar and of the lines (the job's name); none when empty.
    quiet : bool
        Show nothing.
    echo : callable, optional
        Where the lines go instead of stderr (one string a call); with ``echo`` there is never
        a bar.

    Examples
    --------
    >>> lines = []
    >>> with Progress(20, unit="case", desc="grid", echo=lines.append) as p:
    ...     for _ in range(20):
    ...         p.add()
    >>> len(lines), lines[0].split(",")[0], lines[-1].split(",")[0]
    (10, 'grid:  10% 2/20 cases', 'grid: 100% 20/20 cases')
    >>> with Progress(5, quiet=True) as p:  # nothing shown
    ...     p.add(5)
    >>> p.done
    5
    """

    def __init__(self, total: int, *, unit: str = "run", desc: str = "", quiet: bool = False,
                 echo: Callable[[str], None] | None = None) -> None:
        self.total, self.done, self.quiet = int(total), 0, quiet or total <= 0
        self.unit, self.desc = unit, desc
        self.echo = echo or (lambda s: print(s, file=sys.stderr, flush=True))
        self.t0 = time.perf_counter()
        self.next_tenth = 1
        self.bar: Any = None
        if not self.quiet and echo is None and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, unit=unit, desc=desc or None, file=sys.stderr,
                            dynamic_ncols=True)

    def add(self, n: int = 1) -> None:
        """``n`` more units done.

        Parameters
        ----------
        n : int
            Units just finished; a step that crosses several tenths of the work writes one
            line.

        Examples
        --------
        >>> lines = []
        >>> p = Progress(4, echo=lines.append)
        >>> p.add(3)
        >>> p.done, lines[0].split(",")[0]
        (3, ' 75% 3/4 runs')
        """
        self.done += n
        if self.quiet:
            return
        if self.bar is not None:
            self.bar.update(n)
            return
        tenth = min(10, self.done * 10 // self.total)
        if tenth >= self.next_tenth:  # one line for the tenths this step crossed
            el = time.perf_counter() - self.t0
            rate = self.done / el if el > 0 else float("inf")
            eta = (self.total - self.done) / rate if rate > 0 else 0.0
            speed = (f"{rate:.0f} {self.unit}s/s" if rate >= 100 else
                     f"{rate:.3g} {self.unit}s/s" if rate >= 1 else f"{1 / rate:.3g} s/{self.unit}")
            head = f"{self.desc}: " if self.desc else ""
            self.echo(f"{head}{self.done * 100 // self.total:3d}% {self.done}/{self.total} "
                      f"{self.unit}s, {speed}, {seconds(el)} elapsed, ETA {seconds(eta)}")
            self.next_tenth = tenth + 1

    def close(self) -> None:
        """End the bar (the lines need no end).

        Examples
        --------
        >>> p = Progress(2, echo=print)
        >>> p.add(2)  # doctest: +ELLIPSIS
        100% 2/2 runs, ... elapsed, ETA 1 s
        >>> p.close()
        >>> p.bar is None
        True
        """
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def track(items: Iterable[T], *, total: int | None = None, unit: str = "run", desc: str = "",
          quiet: bool = False) -> Iterator[T]:
    """Iterate over ``items``, showing a :class:`Progress` of them (``total`` defaults to
    ``len(items)``).

    Parameters
    ----------
    items : iterable
        What to iterate over; an iterable without ``len`` is read into a list first unless
        ``total`` is given.
    total : int, optional
        Units of work; default ``len(items)``.
    unit, desc, quiet
        As :class:`Progress`.

    Yields
    ------
    object
        Each item of ``items``, in order; the progress advances after the caller's work on
        it.

    Examples
    --------
    >>> [x * x for x in track(range(4), unit="part", quiet=True)]
    [0, 1, 4, 9]
    >>> sum(track((i for i in range(10)), total=10, quiet=True))
    45
    """
    items = list(items) if total is None and not hasattr(items, "__len__") else items
    n = len(items) if total is None else total  # type: ignore[arg-type]
    with Progress(n, unit=unit, desc=desc, quiet=quiet) as progress:
        for item in items:
            yield item
            progress.add()


__all__ = ["Progress", "seconds", "track"]
