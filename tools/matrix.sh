# Sourced by myoskin.sh: the Blender test matrix. Four Blenders, each a ctest label:
#   blender-3.4  Debian 12's package          (Python 3.11)
#   blender-4.3  Debian 13's package          (Python 3.13)
#   blender-4.5  the official build as `bpy`  (Python 3.11, Debian 12's interpreter, in a venv)
#   blender-5.2  the official build as `bpy`  (Python 3.13, Debian 13's interpreter, in a venv)
# The host provides one Debian release; the other comes from a debootstrap chroot that is made once under
# the build folder and reused (build/chroot-<suite>). The core is built once per release (per Python):
# the host's in build/, the chroot's in build/<suite>/. bpy wheels are downloaded once into build/wheels.
# MYOSKIN_MATRIX=host limits everything to the host's own Blender (a quick local loop).

MATRIX_MIRROR="${MYOSKIN_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
MATRIX_BPY_311="4.5.15"   # blender-4.5 (4.5 LTS wheels are built for Python 3.11)
MATRIX_BPY_313="5.2.3"    # blender-5.2 (5.2 LTS wheels are built for Python 3.13)
MATRIX_EXTRA_PACKAGES=(python3-venv python3-pip ca-certificates xauth)

matrix_host_suite() { . /etc/os-release; echo "${VERSION_CODENAME:-unknown}"; }
matrix_other_suite() { case "$1" in bookworm) echo trixie ;; trixie) echo bookworm ;; *) echo "" ;; esac; }
matrix_suite_python() { case "$1" in bookworm) echo 3.11 ;; trixie) echo 3.13 ;; esac; }
matrix_suite_blender() { case "$1" in bookworm) echo 3.4 ;; trixie) echo 4.3 ;; esac; }
matrix_suite_bpy() { case "$1" in bookworm) echo "$MATRIX_BPY_311" ;; trixie) echo "$MATRIX_BPY_313" ;; esac; }
matrix_enabled() { [ "${MYOSKIN_MATRIX:-full}" != host ] && [ -n "$(matrix_other_suite "$(matrix_host_suite)")" ]; }

matrix_chroot_dir() { echo "$BUILD/chroot-$1"; }

# The prefix that runs a command in a suite's environment (empty for the host's own suite).
matrix_runner() {
  local suite="$1"
  [ "$suite" = "$(matrix_host_suite)" ] && return 0
  local shared="${MYOSKIN_SHARED_DIR:-$ROOT/../shared}" binds=(--bind "$ROOT" --bind "$BUILD")
  [ -d "$shared" ] && binds+=(--bind "$(cd "$shared" && pwd)")
  printf '%s ' "$ROOT/tools/in_chroot.sh" "$(matrix_chroot_dir "$suite")" "${binds[@]}" --
}

matrix_suite_build_dir() {
  if [ "$1" = "$(matrix_host_suite)" ]; then echo "$BUILD"; else echo "$BUILD/$1"; fi
}

# Make (once) and update the other release's chroot with the project's packages.
matrix_setup_chroot() {
  local suite="$1" dir; dir="$(matrix_chroot_dir "$suite")"
  local want; want="$(printf '%s\n' "$suite" "${PACKAGES[@]}" "${MATRIX_EXTRA_PACKAGES[@]}" | sha1sum | cut -d' ' -f1)"
  if [ -f "$dir/.myoskin-packages" ] && [ "$(cat "$dir/.myoskin-packages")" = "$want" ]; then
    log "chroot $suite ready ($dir)"; return
  fi
  if [ ! -x "$dir/usr/bin/apt-get" ]; then
    log "creating the Debian $suite chroot in $dir (debootstrap, once)"
    rm -rf "$dir.partial"
    debootstrap --variant=minbase "$suite" "$dir.partial" "$MATRIX_MIRROR" >"$BUILD/debootstrap-$suite.log" 2>&1 \
      || { tail -20 "$BUILD/debootstrap-$suite.log" >&2; echo "myoskin: debootstrap $suite failed" >&2; exit 1; }
    mv "$dir.partial" "$dir"
  fi
  local security="${MATRIX_MIRROR%/debian}/debian-security"
  printf 'deb %s %s main\ndeb %s %s-updates main\ndeb %s %s-security main\n' \
    "$MATRIX_MIRROR" "$suite" "$MATRIX_MIRROR" "$suite" "$security" "$suite" >"$dir/etc/apt/sources.list"
  cp /etc/resolv.conf "$dir/etc/resolv.conf"
  log "installing the project's packages in the $suite chroot"
  "$ROOT/tools/in_chroot.sh" "$dir" -- bash -c "apt-get update -q && DEBIAN_FRONTEND=noninteractive \
      apt-get install -y -q --no-install-recommends ${PACKAGES[*]} ${MATRIX_EXTRA_PACKAGES[*]}" \
      >"$BUILD/chroot-$suite-packages.log" 2>&1 \
    || { tail -20 "$BUILD/chroot-$suite-packages.log" >&2; echo "myoskin: packages in the $suite chroot failed" >&2; exit 1; }
  echo "$want" >"$dir/.myoskin-packages"
}

# Download (once) the pinned bpy wheel for a suite's Python, with its dependencies, into build/wheels.
matrix_fetch_bpy() {
  local suite="$1" version py; version="$(matrix_suite_bpy "$suite")"; py="$(matrix_suite_python "$suite")"
  local dest="$BUILD/wheels/cp${py/./}"
  if compgen -G "$dest/bpy-$version-*.whl" >/dev/null; then return; fi
  log "downloading bpy $version for Python $py into $dest (once)"
  mkdir -p "$dest"
  /usr/bin/python3 -m pip download -q --only-binary=:all: --python-version "$py" --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
    -d "$dest" "bpy==$version" 2> >(grep -v "is ignored" >&2) || { echo "myoskin: could not download bpy $version" >&2; exit 1; }
}

# A venv with the pinned bpy for a suite's Python (inside that suite's environment).
matrix_setup_bpy() {
  local suite="$1" version py runner; version="$(matrix_suite_bpy "$suite")"; py="$(matrix_suite_python "$suite")"
  local venv="$BUILD/bpy-$version"
  [ -f "$venv/.myoskin-ready" ] && return
  matrix_fetch_bpy "$suite"
  log "installing bpy $version into $venv"
  runner="$(matrix_runner "$suite")"
  rm -rf "$venv"
  $runner /usr/bin/python3 -m venv "$venv"
  $runner env -u PIP_FIND_LINKS -u PIP_CONSTRAINT "$venv/bin/python" -m pip install -q --no-index --find-links "$BUILD/wheels/cp${py/./}" "bpy==$version" \
    || { echo "myoskin: installing bpy $version failed" >&2; exit 1; }
  touch "$venv/.myoskin-ready"
}

# Everything the matrix needs beyond the host's packages.
matrix_setup() {
  matrix_enabled || return 0
  local host other; host="$(matrix_host_suite)"; other="$(matrix_other_suite "$host")"
  command -v debootstrap >/dev/null || { echo "myoskin: debootstrap missing" >&2; exit 1; }
  mkdir -p "$BUILD"
  matrix_setup_chroot "$other"
  matrix_setup_bpy "$host"
  matrix_setup_bpy "$other"
}

# Build the core and stage the add-on for the other release's Python, inside its chroot.
matrix_build() {
  matrix_enabled || return 0
  local other; other="$(matrix_other_suite "$(matrix_host_suite)")"
  local dir runner; dir="$(matrix_suite_build_dir "$other")"; runner="$(matrix_runner "$other")"
  # A unity build in batches of 8 (only the core and the module are built here): 161 CPU s from scratch against
  # 252 file by file (measured in the trixie chroot, stop 26). With the chroot's pybind11 when it reads numpy 2's
  # arrays, else the pinned one (myoskin.sh, pybind11_cmake_dir); a tree configured without the unity setting or with
  # another pybind11 is configured again.
  local pybind11; pybind11="$(pybind11_cmake_dir "$(matrix_chroot_dir "$other")")"
  if [ "$(cache_value "$dir/CMakeCache.txt" CMAKE_UNITY_BUILD)" != ON ] \
      || [ "$(cache_value "$dir/CMakeCache.txt" pybind11_DIR)" != "$pybind11" ]; then
    $runner cmake -S "$ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=/usr/bin/python3 \
      -DMYOSKIN_BUILD_BENCHMARKS=OFF -DMYOSKIN_BUILD_TESTS=OFF -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=8 \
      -Dpybind11_DIR:PATH="$pybind11"
  fi
  $runner cmake --build "$dir" -j "$JOBS" --target myoskin stage_addon
}

# Every Blender of the matrix, one line each: "LABEL<TAB>BUILD<TAB>COMMAND..." where COMMAND (runner prefix
# included) runs a Blender script the way `blender -b --factory-startup --python-exit-code 1 --addons
# myoskin --python` does; the script path follows it.
matrix_blenders() {
  local suite suites=("$(matrix_host_suite)")
  matrix_enabled && suites+=("$(matrix_other_suite "${suites[0]}")")
  for suite in "${suites[@]}"; do
    local runner build bpyv; runner="$(matrix_runner "$suite")"; build="$(matrix_suite_build_dir "$suite")"
    bpyv="$(matrix_suite_bpy "$suite")"
    printf 'blender-%s\t%s\t%sblender -b --factory-startup --python-exit-code 1 --addons myoskin --python\n' \
      "$(matrix_suite_blender "$suite")" "$build" "$runner"
    if matrix_enabled; then
      printf 'blender-%s\t%s\t%s%s/bpy-%s/bin/python %s/tests/blender/bpy_main.py --addons myoskin --python-exit-code 1 --python\n' \
        "${bpyv%.*}" "$build" "$runner" "$BUILD" "$bpyv" "$ROOT"
    fi
  done
}

# tests/CMakeLists.txt's view of the matrix: a myoskin_blender_flavour() per Blender, a myoskin_python_tier()
# for the other release's Python.
matrix_write_cmake() {
  local out="$BUILD/matrix.cmake" tmp="$BUILD/matrix.cmake.tmp" label build cmd
  {
    echo "# Written by tools/matrix.sh (myoskin.sh); read by tests/CMakeLists.txt."
    while IFS=$'\t' read -r label build cmd; do
      printf 'myoskin_blender_flavour(%s BUILD "%s" COMMAND %s)\n' "$label" "$build" "$cmd"
    done < <(matrix_blenders)
    if matrix_enabled; then
      local other; other="$(matrix_other_suite "$(matrix_host_suite)")"
      printf 'myoskin_python_tier(python-%s BUILD "%s" RUNNER %s)\n' "$(matrix_suite_python "$other")" \
        "$(matrix_suite_build_dir "$other")" "$(matrix_runner "$other")"
    fi
  } >"$tmp"
  if ! cmp -s "$tmp" "$out"; then mv "$tmp" "$out"; else rm -f "$tmp"; fi
}
