#!/usr/bin/env bash
# The whole test suite, as the README's second command. It first provisions the tools some
# tests compare against, under target/tools (nothing outside the repository, no root):
# OpenImageIO (idiff, oiiotool, its Python module), kubernetes-validate (Kubernetes' schemas, for
# the farm's Job manifest) and, unless one is installed, a static ffmpeg (imageio-ffmpeg's build),
# all from PyPI. Then it runs `cargo test --release`, which reuses
# what the README's first command compiled. Extra arguments go to cargo test.
set -euo pipefail
cd "$(dirname "$0")/.."

tools="$PWD/target/tools"
# Versions the suite was checked with.
pins=(openimageio==3.2.2.0 imageio-ffmpeg==0.8.1 kubernetes-validate==1.37.0)
if ! "$tools/bin/python" -c "import OpenImageIO, imageio_ffmpeg, kubernetes_validate" 2>/dev/null; then
    echo "provisioning OpenImageIO, ffmpeg and kubernetes-validate under target/tools (once; about 100 MB from PyPI)" >&2
    if ! python3 -m venv "$tools"; then
        echo "python3 with the venv module is needed to provision the test tools" >&2
        echo "(Debian/Ubuntu: apt-get install python3-venv)" >&2
        exit 1
    fi
    "$tools/bin/pip" install --quiet --disable-pip-version-check "${pins[@]}"
fi
export STEREOTRACE_OIIO_BIN="$tools/bin"
export STEREOTRACE_OIIO_PYTHON="$tools/bin/python"
if ! command -v ffmpeg >/dev/null 2>&1; then
    mkdir -p "$tools/ffmpeg"
    ln -sf "$("$tools/bin/python" -c 'import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())')" \
        "$tools/ffmpeg/ffmpeg"
    export PATH="$tools/ffmpeg:$PATH"
fi
exec cargo test --release "$@"
