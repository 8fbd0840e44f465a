#!/usr/bin/env bash
# Installs every Debian package Stroma needs to build, test and benchmark.
# Non-interactive and idempotent: only packages that are missing are installed.
# Usage: scripts/setup.sh        (as root, or with sudo available)
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config
  # numerics: Eigen, SuiteSparse (CHOLMOD) with a fast threaded BLAS, LAPACK (rods: banded Cholesky)
  libeigen3-dev libsuitesparse-dev libopenblas0-pthread liblapack-dev
  # scenario files, CLI, logging
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  # SOFA scenes (.scn XML); compressed VTU meshes (zlib)
  libtinyxml2-dev zlib1g-dev
  # DDS (Eclipse Cyclone DDS C API + idlc; its DDS Security plugins come with libddsc), and
  # openssl for `stroma security init` (libssl-dev: it hashes the identities' subjects)
  cyclonedds-dev cyclonedds-tools openssl libssl-dev
  # DDS interoperability test (a Fast DDS client from the same IDL)
  libfastrtps-dev fastddsgen
  # collision benchmark against FCL
  libfcl-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # the sanitizer stage and the fuzz targets: clang with its runtimes (ASan, UBSan, libFuzzer)
  clang libclang-rt-14-dev
  # off-screen rendering (OSMesa: software OpenGL, no display), PNG frames, MP4 video
  libosmesa6-dev libpng-dev ffmpeg
  # the peer in the accuracy benchmark (Bullet's soft bodies), meshes from .geo files, plots
  libbullet-dev libbullet-extras-dev gmsh gnuplot-nox
  # surface checks when (re)building shipped meshes (scripts/meshes/)
  tetgen
  # `stroma mesh`: CGAL's Mesh_3 (header-only; pulls Boost, GMP, MPFR)
  libcgal-dev
  # the Python module (import stroma) and its tests
  python3-dev pybind11-dev python3-numpy python3-pytest python3-venv python3-pip
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
