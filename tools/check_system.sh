#!/usr/bin/env bash
# Checks the shared libraries that Blender's bpy module and the EGL/OpenGL tests need, what
# the OpenXR test runtime is built with, and (Debian/Ubuntu) a CPU OpenCL driver of the system.
# On Debian/Ubuntu, as root, installs the missing ones (saying which); otherwise prints the
# apt-get line and fails. Nothing is installed when everything is already present.
set -euo pipefail

# library soname -> Debian package that provides it
declare -A NEEDED=(
  [libX11.so.6]=libx11-6 [libXrender.so.1]=libxrender1 [libXfixes.so.3]=libxfixes3
  [libXi.so.6]=libxi6 [libxkbcommon.so.0]=libxkbcommon0 [libSM.so.6]=libsm6
  [libICE.so.6]=libice6 [libXext.so.6]=libxext6 [libGL.so.1]=libgl1 [libEGL.so.1]=libegl1
  [libEGL_mesa.so.0]=libegl-mesa0 [libvulkan.so.1]=libvulkan1
)
missing=()
for lib in "${!NEEDED[@]}"; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || missing+=("${NEEDED[$lib]}")
done
# llvmpipe (software OpenGL through EGL) lives in the Mesa DRI package.
compgen -G "/usr/lib/*/dri/swrast_dri.so" >/dev/null || missing+=(libgl1-mesa-dri)
# The tests' OpenXR runtime (tests/xr_runtime) is C, built with the system compiler against the
# OpenXR headers (the loader itself comes with pyopenxr).
command -v cc >/dev/null || missing+=(gcc)
[ -f /usr/include/openxr/openxr_platform.h ] || missing+=(libopenxr-dev)
[ -f /usr/include/EGL/egl.h ] || missing+=(libegl-dev)
[ -f /usr/include/GL/gl.h ] || missing+=(libgl-dev)
# A CPU OpenCL driver registered with the system. The bundled one (pocl-binary-distribution 3.0,
# LLVM 14, the newest on PyPI) cannot build for CPUs newer than LLVM 14 knows ("unknown target
# CPU 'generic'", e.g. AMD Zen 5); Debian's PoCL (3.1, LLVM 15) can. The extension chooses the
# first device that builds a probe program (btf_addon/cl/devices.py), so both may be present.
if command -v apt-get >/dev/null && ! dpkg -s pocl-opencl-icd >/dev/null 2>&1; then
  missing+=(pocl-opencl-icd)
fi

if [ ${#missing[@]} -eq 0 ]; then
  echo "system libraries: all present"
  exit 0
fi
echo "system libraries missing, from Debian packages: ${missing[*]}"
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "installing them with apt-get (root)"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
else
  echo "install them with: sudo apt-get install ${missing[*]}" >&2
  exit 1
fi
