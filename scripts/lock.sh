#!/usr/bin/env bash
# Regenerate requirements.lock, the pinned and hashed runtime dependencies that the Dockerfile
# installs in a layer of their own, from pyproject.toml (uv, from PyPI: `pip install uv`).
# Pins already in the lock are kept unless pyproject.toml needs others; pass --upgrade to move
# everything to the newest allowed versions. The image is Linux x86_64 with Python 3.11.
set -euo pipefail
cd "$(dirname "$0")/.."
exec uv pip compile pyproject.toml \
    --python-version 3.11 --python-platform x86_64-unknown-linux-gnu \
    --generate-hashes --custom-compile-command "scripts/lock.sh" \
    --output-file requirements.lock "$@"
