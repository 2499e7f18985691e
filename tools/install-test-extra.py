"""Installs the `test` extra of python/pyproject.toml (PyTorch, pytest,
mypy, ruff, numpy) into the running interpreter's environment, without
building the package itself: tools/test.sh runs it in the background while
the Rust tests build, so that the download overlaps them.

    .venv-test/bin/python tools/install-test-extra.py
"""

import subprocess
import sys
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python < 3.11: the full install does it all later.
    print("install-test-extra: no tomllib before Python 3.11; skipped")
    sys.exit(0)

PYPROJECT = Path(__file__).resolve().parents[1] / "python" / "pyproject.toml"

extra = tomllib.loads(PYPROJECT.read_text())["project"]["optional-dependencies"]["test"]
subprocess.run(
    [sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-cache-dir", *extra],
    check=True,
)
