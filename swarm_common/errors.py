"""The exit-code contract of every command (docs/reference/contract.md#s2).

``0`` success, ``2`` bad input (one line on stderr naming the flag or file and what is wrong, no
traceback), ``1`` runtime failure.  Loaders raise :class:`InputError`; command entry points wrap
their body in :func:`run_cli`, which turns it into that one line and exit code 2.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

EXIT_OK = 0
EXIT_RUNTIME = 1
EXIT_BAD_INPUT = 2


class InputError(ValueError):
    """Bad user input: a flag, a file or a value. The message is the whole line shown to the user.

    It should name the flag or file first, e.g.
    ``"--swarm-size: must be a positive integer, got -3"`` or
    ``"worlds/foo.yaml: unknown key 'workstaions' (did you mean 'workstations'?)"``.
    """


def did_you_mean(word: str, choices) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest of ``choices``, else ``""``."""
    import difflib

    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def unknown_name(prefix: str, kind: str, name: str, names, hint: str = "") -> InputError:
    """The error for a name that is none of ``names``: ``"<prefix>unknown <kind> '<name>' (did
    you mean ...); available: a, b<hint>"``."""
    names = list(names)
    available = ", ".join(names) if names else "none"
    return InputError(f"{prefix}unknown {kind} '{name}'{did_you_mean(name, names)}; "
                      f"available: {available}{hint}")


def read_yaml(path, missing: Exception | None = None):
    """The YAML document of the file at ``path``.

    Args:
        path: a ``pathlib.Path``.
        missing: raised if there is no such file (default: ``InputError("<path>: no such
            file")``).

    Raises:
        InputError: the file is not readable YAML (the first line of the parser's message).
    """
    import yaml

    if not path.is_file():
        raise missing if missing is not None else InputError(f"{path}: no such file")
    try:
        return yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"{path}: not readable YAML ({exc})".splitlines()[0]) from None


def check_keys(where: str, mapping, allowed, required=()) -> None:
    """A strict loader's key check: every key of ``mapping`` is ``allowed``, every ``required``
    one is there.

    Raises:
        InputError: ``"<where>: unknown key 'k' (did you mean ...)"`` or
            ``"<where>: missing key 'k'"``, for the first such key.
    """
    for key in mapping:
        if key not in allowed:
            raise InputError(f"{where}: unknown key '{key}'{did_you_mean(str(key), allowed)}")
    for key in required:
        if key not in mapping:
            raise InputError(f"{where}: missing key '{key}'")


def run_cli(prog: str, body: Callable[[], int | None]) -> int:
    """Run a command's body and map errors onto the exit-code contract.

    Args:
        prog: the command's name, prefixed to the one-line error (``"swarm-sim: ..."``).
        body: the command; returns an exit code or ``None`` for 0.

    Returns:
        The exit code: the body's, or 2 for :class:`InputError`, 130 for Ctrl-C.
    """
    try:
        code = body()
    except InputError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130
    return EXIT_OK if code is None else int(code)
