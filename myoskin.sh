#!/usr/bin/env bash
# Myoskin's one entry point: installs missing Debian packages, builds, and runs the demo or the tests.
#   ./myoskin.sh demo [OUTPUT_DIR]   setup + build + the main job (default character in Blender) -> out/demo
#   ./myoskin.sh test                setup + build + every test tier (C++, Python, Blender) through ctest
#   ./myoskin.sh render-muscles [OUTPUT_DIR]  extract + render the MakeHuman characters' muscles -> out/muscles
#   ./myoskin.sh gallery [OUTPUT_DIR]  the README's pictures: bent joints under LBS, DQS and Myoskin -> docs/gallery
#   ./myoskin.sh bench               setup + build + the speed and skin-quality benchmarks (printed, never
#                                    asserted; fails when a character of the Blender quality bench does not bind)
#   ./myoskin.sh build               setup + build only (and the packages in build/dist: the Blender 4.2+
#                                    extension and the legacy zip for 3.4, each with the core for 3.11 and 3.13)
#   ./myoskin.sh setup               install missing Debian packages only
# Environment: MYOSKIN_BUILD_DIR (default ./build), MYOSKIN_JOBS (default: number of cores),
#   MYOSKIN_SHARED_DIR (default ../shared), MYOSKIN_MATRIX (full: every Blender of the matrix, the default;
#   host: the host's Debian Blender only), MYOSKIN_TEST_ARGS (extra ctest arguments, e.g. "-L blender-5.2"),
#   MYOSKIN_SANITIZE (1: the sanitize and fuzz labels' quick scope, the default; full: every test; 0: neither).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
BUILD="$(realpath -m "${MYOSKIN_BUILD_DIR:-$ROOT/build}")"
JOBS="${MYOSKIN_JOBS:-$(nproc)}"
# What the build needs (installed first), and what only the tests and the matrix need (installed in the
# background while the host builds); the chroot gets both.
BUILD_PACKAGES=(g++ cmake make libcgal-dev libopenmesh-dev libglm-dev libeigen3-dev pybind11-dev python3-dev
                libtinygltf-dev nlohmann-json3-dev libtbb-dev libgtest-dev libbenchmark-dev python3-pip)
RUN_PACKAGES=(python3-numpy python3-pytest python3-venv blender xvfb xauth debootstrap)
PACKAGES=("${BUILD_PACKAGES[@]}" "${RUN_PACKAGES[@]}")
# The sanitizer and fuzz tiers (host only: clang with its ASan/UBSan/libFuzzer runtimes; the same names on
# Debian 12 and 13), labels sanitize and fuzz. MYOSKIN_SANITIZE: 1 (default) the quick scope (tests that repeat
# the same code over more seeds left out, see tests/CMakeLists.txt), full every test, 0 neither tier.
SANITIZE_PACKAGES=(clang libclang-rt-dev)
SANITIZE="${MYOSKIN_SANITIZE:-1}"
# Debian's cmake: a pip-installed CMake 4 may come first on PATH.
CMAKE=/usr/bin/cmake; [ -x "$CMAKE" ] || CMAKE=cmake
CTEST=/usr/bin/ctest; [ -x "$CTEST" ] || CTEST=ctest

# Each line carries the seconds since the command started, so a CI log shows where the time goes.
log() { printf '\033[1mmyoskin:\033[0m [%ss] %s\n' "$SECONDS" "$*"; }
# shellcheck source=tools/matrix.sh
. "$ROOT/tools/matrix.sh"
# shellcheck source=tools/package.sh
. "$ROOT/tools/package.sh"

# Install whichever of the given Debian packages are missing (as root, or through sudo).
APT_UPDATED=0
install_packages() {
  local missing=() p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -gt 0 ] || return 0
  log "installing missing Debian packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "myoskin: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
    sudo="sudo"
  fi
  [ "$APT_UPDATED" = 1 ] || $sudo apt-get update -q
  APT_UPDATED=1
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
}

# The build's packages now; the rest (Blender, the test tools) and the matrix's setup (debootstrap, the chroot's
# packages, the bpy wheels: network and disk bound) in the background while the host builds (setup_wait).
SETUP_PID=""
setup() {
  local wanted=("${BUILD_PACKAGES[@]}")
  [ "$SANITIZE" = 0 ] || wanted+=("${SANITIZE_PACKAGES[@]}")
  install_packages "${wanted[@]}"
  # Not root: sudo asks for its password here, not from the background.
  if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null; then
    local p
    for p in "${RUN_PACKAGES[@]}"; do
      dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || { sudo -v; break; }
    done
  fi
  mkdir -p "$BUILD"
  log "Blender, the test tools and the matrix are set up in the background ($BUILD/setup-background.log)"
  ( install_packages "${RUN_PACKAGES[@]}"; matrix_setup; setup_numpy2 ) >"$BUILD/setup-background.log" 2>&1 &
  SETUP_PID=$!
  trap 'setup_wait quiet' EXIT
}

# Waits for the background setup and prints its log; stops when it failed. With `quiet` (on exit, after a failure)
# it still waits, so an apt or debootstrap run is never cut off halfway, and shows the log's end if that failed too.
setup_wait() {
  [ -n "$SETUP_PID" ] || return 0
  local status=0 pid="$SETUP_PID"
  SETUP_PID=""
  log "waiting for the background setup ($BUILD/setup-background.log)"
  wait "$pid" || status=$?
  if [ "${1:-}" = quiet ]; then
    [ "$status" = 0 ] || { tail -20 "$BUILD/setup-background.log" >&2; echo "myoskin: the background setup failed too" >&2; }
    return 0
  fi
  cat "$BUILD/setup-background.log"
  [ "$status" = 0 ] || { echo "myoskin: the background setup failed (above)" >&2; exit 1; }
  log "background setup done"
}

# A pinned wheel from PyPI unpacked into DEST (pip --target), downloaded once into WHEELS; DEST's marker names the
# version, so a new pin unpacks again. Everything it prints goes to stderr. Returns 1 when the download fails;
# exits when the unpack does.
pinned_wheel() {
  local name="$1" version="$2" wheels="$3" dest="$4"
  [ "$(cat "$dest/.myoskin-ready" 2>/dev/null)" = "$version" ] && return 0
  if ! compgen -G "$wheels/$name-$version-*.whl" >/dev/null; then
    log "downloading $name $version into $wheels (once)" >&2
    mkdir -p "$wheels"
    /usr/bin/python3 -m pip download -q --disable-pip-version-check --no-deps --only-binary=:all: -d "$wheels" \
      "$name==$version" 2> >(grep -v "is ignored" >&2) >&2 || return 1
  fi
  rm -rf "$dest"
  /usr/bin/python3 -m pip install -q --disable-pip-version-check --root-user-action=ignore --no-deps --no-index \
    --target "$dest" "$wheels/$name-$version-"*.whl >&2 || { echo "myoskin: could not unpack $name $version" >&2; exit 1; }
  echo "$version" >"$dest/.myoskin-ready"
}

# pybind11 2.12 or newer: older ones (Debian 12 has 2.10) read numpy 2's arrays with numpy 1's layout and crash the
# interpreter on the first array passed in. Debian's when it is new enough (under ROOT_PREFIX: a chroot's), else the
# pinned one from PyPI, unpacked into the build folder (a chroot sees the build folder at the same path). Prints the
# folder of its pybind11Config.cmake; without the download, Debian's, with a warning (the module then works under
# numpy 1 only).
PYBIND11_PIN=2.13.6
pybind11_cmake_dir() {
  local prefix="${1:-}" debian=/usr/lib/cmake/pybind11 version dest="$BUILD/pybind11-$PYBIND11_PIN"
  version="$(sed -n 's/^set(PACKAGE_VERSION "\([0-9.]*\)".*/\1/p' "$prefix$debian/pybind11ConfigVersion.cmake" 2>/dev/null)"
  if [ -n "$version" ] && [ "$(printf '%s\n2.12\n' "$version" | sort -V | head -1)" = 2.12 ]; then
    echo "$debian"
  elif pinned_wheel pybind11 "$PYBIND11_PIN" "$BUILD/wheels/any" "$dest"; then
    echo "$dest/pybind11/share/cmake/pybind11"
  else
    log "warning: could not download pybind11 $PYBIND11_PIN; building with Debian's ${version:-?}, whose module" \
      "crashes under numpy 2" >&2
    echo "$debian"
  fi
}

# The value a CMake cache holds for a variable, whatever its type (empty when absent).
cache_value() { sed -n "s/^$2:[A-Z]*=//p" "$1" 2>/dev/null | head -1; }

# numpy 2 for the host's Python, in build/numpy2-cp<version> (PyPI, pinned, once): the python-numpy2 tier runs the
# tests under it (tests/CMakeLists.txt), as a pipeline with a pip-installed numpy would.
NUMPY2_PIN=2.2.6
setup_numpy2() {
  local tag
  tag="$(/usr/bin/python3 -c 'import sys; print(f"cp{sys.version_info[0]}{sys.version_info[1]}")')"
  pinned_wheel numpy "$NUMPY2_PIN" "$BUILD/wheels/$tag" "$BUILD/numpy2-$tag" \
    || { echo "myoskin: could not download numpy $NUMPY2_PIN" >&2; exit 1; }
}

# Configure once (Release, Blender's Python), then build incrementally.
# The other Debian release's core (its Python) is built in its chroot, in build/<suite>.
build() {
  mkdir -p "$BUILD"
  matrix_write_cmake
  write_sanitize_cmake
  local pybind11; pybind11="$(pybind11_cmake_dir)"
  # Configured once; again when the tree was configured with another pybind11.
  if [ ! -f "$BUILD/CMakeCache.txt" ] || [ "$(cache_value "$BUILD/CMakeCache.txt" pybind11_DIR)" != "$pybind11" ]; then
    "$CMAKE" -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=/usr/bin/python3 \
      -Dpybind11_DIR:PATH="$pybind11"
  fi
  log "build ($BUILD)"
  "$CMAKE" --build "$BUILD" -j "$JOBS"
  setup_wait
  matrix_build
  package
  build_sanitize
}

# The sanitizer build in build/sanitize (clang, ASan + UBSan + LeakSanitizer, the libFuzzer targets; configured
# once, incremental after), and <build>/sanitize.cmake, which puts its tests in the main build's ctest under the
# labels `sanitize` and `fuzz` (tests/CMakeLists.txt).
write_sanitize_cmake() {
  local out="$BUILD/sanitize.cmake" tmp="$BUILD/sanitize.cmake.tmp" runtime="" dir
  {
    echo "# Written by myoskin.sh; read by tests/CMakeLists.txt."
    if [ "$SANITIZE" != 0 ]; then
      dir="$(clang++ -print-runtime-dir 2>/dev/null || true)"
      for f in "$dir/libclang_rt.asan-x86_64.so" "$dir/libclang_rt.asan.so"; do [ -f "$f" ] && runtime="$f" && break; done
      printf 'myoskin_sanitize_tier(BUILD "%s" ASAN_RUNTIME "%s" SCOPE %s)\n' "$BUILD/sanitize" "$runtime" \
        "$([ "$SANITIZE" = full ] && echo full || echo quick)"
    fi
  } >"$tmp"
  if ! cmp -s "$tmp" "$out"; then mv "$tmp" "$out"; else rm -f "$tmp"; fi
}

# A unity build in batches of 8 sources (the core's 56 files in 9 compiler runs: 16.0 min of CPU from scratch
# for the quick scope, against 21.0 min file by file for everything), and only the targets the scope runs.
# A tree configured before the unity setting is configured again with it.
build_sanitize() {
  [ "$SANITIZE" != 0 ] || return 0
  local dir="$BUILD/sanitize" target=sanitize_quick
  [ "$SANITIZE" != full ] || target=all
  local pybind11; pybind11="$(pybind11_cmake_dir)"
  if [ "$(cache_value "$dir/CMakeCache.txt" CMAKE_UNITY_BUILD)" != ON ] \
      || [ "$(cache_value "$dir/CMakeCache.txt" pybind11_DIR)" != "$pybind11" ]; then
    CC=clang CXX=clang++ "$CMAKE" -S "$ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -DMYOSKIN_SANITIZE=ON -DMYOSKIN_FUZZ=ON -DMYOSKIN_BUILD_BENCHMARKS=OFF \
      -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=8 -DPython3_EXECUTABLE=/usr/bin/python3 \
      -Dpybind11_DIR:PATH="$pybind11"
  fi
  log "sanitizer build ($dir, $target)"
  "$CMAKE" --build "$dir" -j "$JOBS" --target "$target"
}

run_tests() {
  log "tests (ctest -j $JOBS)"
  # shellcheck disable=SC2086
  "$CTEST" --test-dir "$BUILD" --output-on-failure -j "$JOBS" --timeout 1500 ${MYOSKIN_TEST_ARGS:-}
}

run_demo() {
  local out="${1:-$ROOT/out/demo}"
  mkdir -p "$out"
  out="$(cd "$out" && pwd)"
  "$BUILD/bin/myoskin" generate arm -o "$out/character"
  BLENDER_USER_SCRIPTS="$BUILD/blender_scripts" blender -b --factory-startup --python-exit-code 1 \
    --addons myoskin --python "$ROOT/examples/demo.py" -- --output "$out"
  log "demo outputs in $out:"
  ls -1 "$out"
}

run_render_muscles() {
  local out="${1:-$ROOT/out/muscles}" shared="${MYOSKIN_SHARED_DIR:-$ROOT/../shared}"
  mkdir -p "$out"
  BLENDER_USER_SCRIPTS="$BUILD/blender_scripts" blender -b --factory-startup --python-exit-code 1 \
    --addons myoskin --python "$ROOT/examples/render_muscles.py" -- -o "$out" \
    "$shared/characters/makehuman_muscular_male/makehuman_muscular_male.glb" \
    "$shared/characters/makehuman_neutral/makehuman_neutral.glb"
}

run_gallery() {
  local out="${1:-$ROOT/docs/gallery}" shared="${MYOSKIN_SHARED_DIR:-$ROOT/../shared}"
  mkdir -p "$out"
  BLENDER_USER_SCRIPTS="$BUILD/blender_scripts" blender -b --factory-startup --python-exit-code 1 \
    --addons myoskin --python "$ROOT/examples/render_gallery.py" -- -o "$out" \
    "$shared/characters/makehuman_muscular_male/makehuman_muscular_male.glb"
  rm -f "$out"/*.png
}

run_bench() {
  log "building the benchmarks (target benchmarks: not part of the test build)"
  "$CMAKE" --build "$BUILD" -j "$JOBS" --target benchmarks
  log "bench_skin_quality (core: LBS, DQS, Myoskin at bent joints)"
  PYTHONPATH="$BUILD/blender_scripts/addons/myoskin" /usr/bin/python3 "$ROOT/benchmarks/bench_skin_quality.py" \
    "${MYOSKIN_SHARED_DIR:-$ROOT/../shared}"
  # The same measures through Blender's own Armature modifier (LBS, Preserve Volume, Myoskin bound), beside the
  # core's skinner on the same skin, on every Blender of the matrix (~40 s each); a character that fails to bind
  # fails the bench once every benchmark has run.
  local label build cmd shared quality_failed=()
  shared="$(cd "${MYOSKIN_SHARED_DIR:-$ROOT/../shared}" 2>/dev/null && pwd || echo "${MYOSKIN_SHARED_DIR:-$ROOT/../shared}")"
  while IFS=$'\t' read -r label build cmd; do
    log "bench_blender_skin_quality ($label)"
    # shellcheck disable=SC2086
    BLENDER_USER_SCRIPTS="$build/blender_scripts" $cmd "$ROOT/benchmarks/bench_blender_skin_quality.py" -- "$shared" \
      2>&1 | grep -v -e "^Blender quit" -e "^Read prefs" -e "^Freeing memory" -e "mounted file-systems" -e "^Info:" \
                    -e "| INFO: " -e "^Data are loaded" -e "^glTF import finished" || quality_failed+=("$label")
  done < <(matrix_blenders)
  log "bench_roundoff (core: muscles under the round-off Blender's importer leaves, against the file's own numbers)"
  PYTHONPATH="$BUILD/blender_scripts/addons/myoskin" /usr/bin/python3 "$ROOT/benchmarks/bench_roundoff.py" \
    "${MYOSKIN_SHARED_DIR:-$ROOT/../shared}"
  log "bench_limits (core: time and peak memory at ~1M vertices and with 500 muscles)"
  PYTHONPATH="$BUILD/blender_scripts/addons/myoskin" /usr/bin/python3 "$ROOT/benchmarks/bench_limits.py"
  for b in "$BUILD"/bin/bench_*; do
    log "$(basename "$b")"
    if [ "$(basename "$b")" = bench_skinning ]; then "$b" --export "$BUILD/bench_skinning_data"; else "$b"; fi
  done
  # Blender's Armature modifier on the same skin and weights, against the core figures just measured.
  for t in 1 2; do
    log "bench_blender_skinning (blender -t $t)"
    BLENDER_USER_SCRIPTS="$BUILD/blender_scripts" blender -b --factory-startup -t "$t" --python-exit-code 1 \
      --addons myoskin --python "$ROOT/benchmarks/bench_blender_skinning.py" -- "$BUILD/bench_skinning_data" \
      --threads "$t" 2>&1 | grep -v -e "^Blender quit" -e "^Read prefs"
  done
  # Playback against the plain Armature modifier, on every Blender of the matrix.
  while IFS=$'\t' read -r label build cmd; do
    log "bench_blender_playback ($label)"
    # shellcheck disable=SC2086
    BLENDER_USER_SCRIPTS="$build/blender_scripts" $cmd "$ROOT/benchmarks/bench_blender_playback.py" 2>&1 \
      | grep -v -e "^Blender quit" -e "^Read prefs" -e "^Freeing memory" -e "mounted file-systems" -e "^Info:" \
             -e "^Read blend" -e "^Saved"
  done < <(matrix_blenders)
  if [ "${#quality_failed[@]}" -gt 0 ]; then
    echo "myoskin: bench_blender_skin_quality failed on ${quality_failed[*]} (a character did not bind: see its ERROR line)" >&2
    return 1
  fi
}

case "${1:-}" in
  setup) setup; setup_wait ;;
  build) setup; build ;;
  test) setup; build; run_tests ;;
  demo) setup; build; run_demo "${2:-}" ;;
  render-muscles) setup; build; run_render_muscles "${2:-}" ;;
  gallery) setup; build; run_gallery "${2:-}" ;;
  bench) setup; build; run_bench ;;
  *) sed -n '2,11p' "$0"; exit 2 ;;
esac
