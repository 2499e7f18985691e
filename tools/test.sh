#!/usr/bin/env bash
# The project's test command (README, .ci/run): everything a new machine
# needs, then every test of the workspace.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace --locked
