"""The wheel's ``nephele`` command is the library's command line: the binary's code."""

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import cli_path


def script():
    """The ``nephele`` script pip installed beside this Python (skips when not installed)."""
    path = Path(sys.executable).parent / "nephele"
    if not path.exists():
        pytest.skip(f"no nephele script at {path}: install the wheel (python/ci.sh does)")
    return path


def run(exe, *args, cwd=None):
    return subprocess.run([str(exe), *map(str, args)], cwd=cwd, capture_output=True, text=True)


def test_the_script_is_the_binary(tmp_path):
    exe, binary = script(), cli_path()
    a, b = run(exe, "--version"), run(binary, "--version")
    assert (a.returncode, a.stdout) == (0, b.stdout)
    # A fit: the same model file, byte for byte.
    for name, tool in (("script", exe), ("binary", binary)):
        proc = run(tool, "fit", "builtin:duck", "-o", tmp_path / f"{name}.ron", "--blobs", 20,
                   "--samples", 2000, "--candidates", 200, "--seed", 3)
        assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "script.ron").read_bytes() == (tmp_path / "binary.ron").read_bytes()
    # An error: the same message and exit code.
    bad = tmp_path / "bad.ron"
    bad.write_text("Scene(\n    target: 5,\n)\n")
    a, b = run(exe, "render", bad), run(binary, "render", bad)
    assert a.returncode == b.returncode == 1
    assert a.stderr == b.stderr and a.stderr.startswith(f"error: {bad}:2:"), a.stderr
    # A usage error is clap's, exit code 2.
    a, b = run(exe, "render", "--no-such-flag"), run(binary, "render", "--no-such-flag")
    assert a.returncode == b.returncode == 2 and a.stderr == b.stderr
