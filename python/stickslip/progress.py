"""Progress of a long command on stderr: a tqdm bar on a terminal, else one line per 10 %.

Written to a log (stderr redirected to a file or a pipe), a bar would be one long line of
carriage returns; there every tenth of the work gets a line of its own instead. Used by
``stickslip sweep`` (variants) and ``stickslip simulate`` (communication steps).
"""

from __future__ import annotations

import math
import shutil
import sys
import time


class Progress:
    """``total`` units of work, ``already`` of them done before this run.

    On a terminal a tqdm bar counts them, with the fields of the last :meth:`advance` beside
    it. Elsewhere each tenth of the remaining work writes ``line`` formatted with those fields
    and ``desc``, ``percent`` (10, 20, ... 100), ``done`` (of ``total``, ``already``
    included), ``total``, ``rate`` (units per second in this run), ``eta`` and ``elapsed``
    (s). ``tty``: None to ask ``stream`` (default: sys.stderr as it is when constructed, not
    as it was at import: a host that redirects it, pytest's capture, would leave a closed
    stream).
    """

    def __init__(
        self,
        total: int,
        line: str,
        already: int = 0,
        tty: bool | None = None,
        stream=None,
        unit: str = "it",
        desc: str = "",
    ):
        stream = sys.stderr if stream is None else stream
        self.total, self.already, self.stream, self.line, self.desc = total, already, stream, line, desc
        self.done = 0
        self.start = time.monotonic()
        self.tty = stream.isatty() if tty is None else tty
        self.next_tenth = 1
        self.bar = None
        if self.tty:
            from tqdm import tqdm

            # a terminal that reports no size (0 x 0) gets 100 x 24: tqdm would draw nothing
            size = shutil.get_terminal_size((100, 24))
            self.bar = tqdm(
                total=total,
                initial=already,
                unit=unit,
                desc=desc or None,
                file=stream,
                smoothing=0.05,
                ncols=size.columns,
                nrows=size.lines or 24,
            )

    def advance(self, n: int = 1, **fields) -> None:
        """``n`` more units done; ``fields`` go beside the bar or into the line."""
        self.done += n
        if self.bar is not None:
            self.bar.set_postfix(fields, refresh=False)
            self.bar.update(n)
            return
        todo = self.total - self.already
        tenth = self.done * 10 // todo if todo > 0 else 10
        if tenth < self.next_tenth:
            return
        elapsed = time.monotonic() - self.start
        rate = self.done / elapsed if elapsed > 0 else math.nan
        eta = (todo - self.done) / rate if rate > 0 else math.nan
        text = self.line.format(
            desc=self.desc,
            percent=10 * tenth,
            done=self.already + self.done,
            total=self.total,
            rate=rate,
            eta=eta,
            elapsed=elapsed,
            **fields,
        )
        print(text, file=self.stream, flush=True)
        self.next_tenth = tenth + 1

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
