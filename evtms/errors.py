"""Exceptions shared by the library; the CLI turns them into exit codes."""


class EvtmsInputError(ValueError):
    """A user-supplied value is not allowed.

    The message is one line that names the bad value and what is allowed; the
    CLI prints it and exits with code 2. A request field the message names is
    written in backticks (```max_points` 0 is not allowed``); the CLI shows it
    as its option (``--max-points 0 is not allowed``).
    """


class EvtmsInterrupted(KeyboardInterrupt):
    """A long job stopped by Ctrl-C; the message is one line saying what stopped and what was kept.

    A KeyboardInterrupt, so that whatever catches Ctrl-C catches it (the
    CLI's exit code 130); raised instead of the bare KeyboardInterrupt once
    the job's worker processes are stopped and its partial state is cleaned
    up (or kept for a resume).
    """
