#!/usr/bin/env python3
"""Fails when a crate in Cargo.lock's resolve (every feature) declares a
`rust-version` newer than the workspace's, so that the version the README
and Cargo.toml state is the true minimum (.ci/run calls it).

Usage: tools/check-rust-version.py   (from anywhere in the repository)
"""

import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent


def version(text: str) -> tuple[int, ...]:
    """'1.85', '1.85.0' or '1.85.1' as three numbers (1.85 is 1.85.0)."""
    parts = [int(part) for part in text.split(".")]
    return tuple(parts + [0] * (3 - len(parts)))


def main() -> int:
    metadata = json.loads(
        subprocess.run(
            ["cargo", "metadata", "--format-version", "1", "--locked", "--all-features"],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    )
    resolved = {node["id"] for node in metadata["resolve"]["nodes"]}
    members = set(metadata["workspace_members"])
    declared = {
        version(p["rust_version"])
        for p in metadata["packages"]
        if p["id"] in members and p.get("rust_version")
    }
    if len(declared) != 1:
        print(f"check-rust-version: the workspace's crates declare {sorted(declared)}; expected one")
        return 1
    (workspace,) = declared
    newer = sorted(
        (version(p["rust_version"]), p["name"], p["version"])
        for p in metadata["packages"]
        if p["id"] in resolved and p.get("rust_version") and version(p["rust_version"]) > workspace
    )
    if newer:
        shown = ", ".join(f"{name} {v} needs {'.'.join(map(str, need))}" for need, name, v in newer)
        print(
            f"check-rust-version: Cargo.toml says rust-version {'.'.join(map(str, workspace[:2]))}, "
            f"but {shown}: raise it to the highest (and say so in the README)"
        )
        return 1
    print(f"check-rust-version: rust-version {'.'.join(map(str, workspace[:2]))} covers every dependency")
    return 0


if __name__ == "__main__":
    sys.exit(main())
