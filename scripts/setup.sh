#!/usr/bin/env bash
# vdbphoton quick start: installs what is missing on Debian 12 (apt-get),
# builds the release binary, and renders the bundled default scene
# (scenes/cloud.toml) to out/cloud.exr with a PNG preview out/cloud.png.
# Usage: bash scripts/setup.sh        (from the repository root)
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES="libopenvdb-dev libboost-dev libtbb-dev libimath-dev g++ pkg-config python3-venv"
missing=""
for p in $PACKAGES; do
    dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
    echo "== installing Debian packages:$missing"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update
    $SUDO apt-get install -y $missing
fi
if ! command -v cargo >/dev/null 2>&1; then
    echo "error: cargo not found; install Rust (https://rustup.rs) and run this again" >&2
    exit 1
fi

echo "== building vdbphoton (release)"
cargo build --release --locked

# Intel Open Image Denoise 2.x for --denoise (not packaged in Debian 12):
# PyPI's pyoidn wheel carries its libraries; vdbphoton finds them in
# target/venv-oidn. Optional: without it everything but --denoise works.
# The default scene is rendered denoised when the library is there.
denoise=--denoise
if ! bash scripts/install_oidn.sh; then
    echo "warning: Open Image Denoise was not installed; --denoise will say how to get it, and the default scene renders without it" >&2
    denoise=
fi

mkdir -p out
echo "== rendering the default scene"
./target/release/vdbphoton render scenes/cloud.toml $denoise -o out/cloud.exr --preview out/cloud.png
echo "== done: out/cloud.exr (linear float RGBA) and out/cloud.png (sRGB preview)"
