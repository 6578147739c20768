#!/usr/bin/env bash
# The whole test suite against the installed extension: Rust unit tests, then pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --quiet
python3 -m pytest -q
