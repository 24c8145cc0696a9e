"""The text log of a run: ``OUT/log.txt``, what rank 0's terminal shows, written line by line.

`pdem run` (`pdem.cli`) calls `start` on rank 0 before the run: from then on rank 0's stdout and
stderr go to the terminal as before and also to the log (a `Tee`). Until the output directory is
known and checked (`pdem.driver.runloop.prepare_output` calls `attach`) the lines wait in memory;
then ``OUT/log.txt`` is opened, truncated by ``--fresh`` and appended to otherwise (a resumed run
adds its lines below the earlier ones, after a header line with the date and the command). Every
line is flushed as it is written, so the log of a run killed by the batch system ends where it
stopped. The progress bar of a terminal is not in the log: its redraws go to the terminal only,
and the progress lines a batch log would show go to the log instead (`log_only`). `stop` puts
the streams back (after the post-processing, whose lines are logged too). Other ranks log nothing.
"""
import sys
import time

from ..version import __version__

LOG = "log.txt"
_active = None  # the Tee of this process (rank 0 of a `pdem run`), or None


class Tee:
    """A text stream that writes to ``terminal`` and to the log file (kept in memory until
    `attach`); both streams of one process share the file."""

    def __init__(self, terminal, sink):
        self.terminal = terminal
        self.sink = sink

    def write(self, text):
        self.terminal.write(text)
        self.sink.write(text)
        return len(text)

    def flush(self):
        self.terminal.flush()
        self.sink.flush()

    def isatty(self):
        return self.terminal.isatty()

    def fileno(self):
        return self.terminal.fileno()

    def __getattr__(self, name):  # encoding, errors ... of the terminal stream
        return getattr(self.terminal, name)


class _Sink:
    """The log file: lines are held until a file is attached, then written and flushed as each
    line ends."""

    def __init__(self):
        self.file = None
        self.pending = []

    def write(self, text):
        if self.file is None:
            self.pending.append(text)
        else:
            self.file.write(text)
            if "\n" in text:
                self.file.flush()

    def flush(self):
        if self.file is not None:
            self.file.flush()


class _RunLog:
    def __init__(self, argv):
        self.argv = argv
        self.sink = _Sink()
        self.streams = (sys.stdout, sys.stderr)
        self.stdout, self.stderr = Tee(sys.stdout, self.sink), Tee(sys.stderr, self.sink)
        sys.stdout, sys.stderr = self.stdout, self.stderr


def start(argv):
    """Rank 0 of `pdem run`: tee stdout and stderr into the log-to-be (``argv``: the command
    line, for the header)."""
    global _active
    if _active is None:
        _active = _RunLog(list(argv))


def attach(out, fresh):
    """Open ``out``/log.txt (truncated if ``fresh``, else appended to) and write what waited."""
    if _active is None or _active.sink.file is not None:
        return
    f = open(out / LOG, "w" if fresh else "a", encoding="utf-8")
    stamp = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    f.write(f"# pdem {__version__}, {stamp}: pdem {' '.join(_active.argv)}\n")
    f.write("".join(_active.sink.pending))
    f.flush()
    _active.sink.file, _active.sink.pending = f, []


def log_only(line):
    """A line for the log and not for the terminal (a progress line while a bar is drawn)."""
    if _active is not None:
        _active.sink.write(line + "\n")


def terminal():
    """The stream rank 0's terminal output goes to (under a Tee: the one it wraps), or None
    outside a logged run. A progress bar draws on it (`set_terminal` while drawing)."""
    return None if _active is None else _active.streams[0]


def set_terminal(stream):
    """Send stdout's terminal half to ``stream`` (a progress bar's proxy that prints above the
    bar); None puts the original back."""
    if _active is not None:
        _active.stdout.terminal = _active.streams[0] if stream is None else stream


def stop():
    """Put stdout and stderr back and close the log."""
    global _active
    if _active is None:
        return
    sys.stdout, sys.stderr = _active.streams
    if _active.sink.file is not None:
        _active.sink.file.close()
    _active = None
