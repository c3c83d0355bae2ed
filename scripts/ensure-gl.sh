#!/usr/bin/env bash
# Make sure an OpenGL 3.3 context can be created through EGL; install Mesa (llvmpipe) when it cannot.
set -u
py=${1:-python3}
packages="libegl1 libegl-mesa0 libgl1-mesa-dri libgl1"
probe() { "$py" -c "import moderngl; moderngl.create_context(standalone=True, backend='egl', require=330).release()" 2>/dev/null; }
if probe; then exit 0; fi
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "OpenGL through EGL is missing; installing Mesa: $packages"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $packages >/dev/null
  probe && exit 0
fi
echo "error: cannot create an OpenGL 3.3 context through EGL; run: sudo apt-get install -y $packages" >&2
exit 1
