#!/usr/bin/env bash
# Installs Intel Open Image Denoise 2.5.1 for `vdbphoton render --denoise`:
# PyPI's pyoidn wheel (its Python module is not used, only the libraries it
# carries, libOpenImageDenoise.so.2 and its CPU device) into the virtual
# environment target/venv-oidn, where vdbphoton looks for it (see
# src/denoise/oidn.rs; VDBPHOTON_OIDN overrides). Needs python3-venv.
# Usage: bash scripts/install_oidn.sh        (from the repository root)
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=target/venv-oidn
LIB="$VENV/lib/python3*/site-packages/pyoidn/oidn/lib/libOpenImageDenoise.so.2"
if compgen -G "$LIB" >/dev/null; then
    exit 0
fi
echo "== installing Intel Open Image Denoise 2.5.1 (PyPI pyoidn) into $VENV"
mkdir -p target
python3 -m venv "$VENV"
"$VENV/bin/pip" install --quiet --no-deps pyoidn==2.5.1
compgen -G "$LIB" >/dev/null
