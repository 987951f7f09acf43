#!/usr/bin/env bash
# Installs the Debian 12 packages that building and testing ldem need (run as root).
set -euo pipefail
PKGS=(
  cmake ninja-build g++            # build
  libcli11-dev libfmt-dev          # command line, formatting
  libtomlplusplus-dev              # case files
  nlohmann-json3-dev               # summary.json read and updated by the analyses
  libboost-math-dev                # Student t quantiles (confidence interval of Paris' m)
  libfftw3-dev pkgconf             # correlated random fields (FFT); pkg-config finds FFTW
  zlib1g-dev                       # compressed VTU snapshots (VTK's zlib block format)
  libeigen3-dev                    # ldem modes: sparse matrices and their factorisation
  libspectra-dev                   # ldem modes: Lanczos shift-invert eigen-solver (lowest modes)
  python3-matplotlib python3-numpy # PNG plots of a run
  pybind11-dev python3-dev         # the Python module (python/)
  python3-pytest                   # tests: the Python module's suite
  python3-vtk9                     # tests: an independent reader of the VTU/PVD output
  libgtest-dev libgmock-dev        # tests
  libbenchmark-dev                 # microbenchmarks (bench/micro.cpp)
  clang libclang-rt-14-dev         # tests: libFuzzer with sanitizers on the case reader
  libopenmpi-dev openmpi-bin       # distributed runs (MPI); tests run 1 to 3 ranks
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all packages present"
  exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "install-deps: missing packages ${missing[*]}; run this script as root" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -q
apt-get install -y -q --no-install-recommends "${missing[@]}"
