"""What a failed command must print, checked once for every test that makes one fail."""

from __future__ import annotations


def error_line(result, status: int) -> str:
    """The one ``Error:`` line of a command that exited with ``status``.

    ``result`` is a click ``Result`` or a ``subprocess.CompletedProcess``. The
    command must have printed, besides ``note:`` lines, that line alone on stderr,
    and no traceback. Tests then check the start of the line: what failed and
    where, not every word of the sentence.
    """
    code = result.exit_code if hasattr(result, "exit_code") else result.returncode
    stderr = result.stderr if isinstance(result.stderr, str) else result.stderr.decode()
    assert code == status, (code, stderr)
    lines = [line for line in stderr.splitlines() if not line.startswith("note: ")]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and stderr.endswith("\n"), stderr
    return lines[0]
