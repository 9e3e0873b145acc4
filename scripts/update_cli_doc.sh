#!/usr/bin/env bash
# Regenerates docs/cli.md from the command-line tool's own command table and flags
# (`subslam cli-reference`). The test CliReferenceIsCurrent fails until this is run after
# a flag or command changes.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${BUILD_DIR:-$ROOT/build}"
cmake --build "$BUILD" --target subslam -j"$(nproc)" > /dev/null
"$BUILD/apps/subslam" cli-reference > "$ROOT/docs/cli.md"
echo "wrote $ROOT/docs/cli.md"
