# Sourced by myoskin.sh: the add-on as users install it, with the core for every Python of the matrix.
#   build/package/myoskin/                 the add-on folder: Python files, _core.cpython-3XX-*.so and
#                                          build_info-3.X.json per Python, libs/cp3XX/ (the core's
#                                          non-toolchain libraries, found through its RPATH $ORIGIN/libs/cp3XX)
#   build/dist/myoskin-<v>.zip             the Blender 4.2+ extension (blender --command extension build)
#   build/dist/myoskin-<v>-legacy.zip      the legacy add-on zip for Blender 3.4 (Preferences > Install)

# Libraries every Linux Blender already has (the C and C++ runtimes): never bundled.
PACKAGE_SYSTEM_LIBS='^(libc|libm|libgcc_s|libstdc\+\+|ld-linux-x86-64|libpthread|libdl|librt)\.so'

package_bundle_libs() {
  local core="$1" suite="$2" dest="$3" runner lib
  runner="$(matrix_runner "$suite")"
  mkdir -p "$dest"
  # shellcheck disable=SC2086
  for lib in $($runner ldd "$core" | awk '$2 == "=>" && $3 ~ /^\// {print $3}'); do
    basename "$lib" | grep -Eq "$PACKAGE_SYSTEM_LIBS" && continue
    $runner cp -L "$lib" "$dest/"
  done
}

package() {
  local out="$BUILD/package" dist="$BUILD/dist" pkg="$BUILD/package/myoskin" suite py tag version
  rm -rf "$out" "$dist"
  mkdir -p "$pkg" "$dist"
  cp -r "$BUILD/blender_scripts/addons/myoskin/." "$pkg/"
  local suites=("$(matrix_host_suite)")
  matrix_enabled && suites+=("$(matrix_other_suite "${suites[0]}")")
  for suite in "${suites[@]}"; do
    py="$(matrix_suite_python "$suite")"; tag="cp${py/./}"
    local staged; staged="$(matrix_suite_build_dir "$suite")/blender_scripts/addons/myoskin"
    cp "$staged"/_core.cpython-"${py/./}"-*.so "$staged/build_info-$py.json" "$pkg/"
    package_bundle_libs "$(echo "$pkg"/_core.cpython-"${py/./}"-*.so)" "$suite" "$pkg/libs/$tag"
  done
  find "$pkg" -name __pycache__ -prune -exec rm -rf {} +
  version="$(sed -n 's/^version = "\(.*\)"$/\1/p' "$pkg/blender_manifest.toml")"
  /usr/bin/python3 -c "import shutil, sys; shutil.make_archive(sys.argv[1], 'zip', sys.argv[2], 'myoskin')" \
    "$dist/myoskin-$version-legacy" "$out"
  if ! matrix_enabled && [ "$(matrix_host_suite)" != trixie ]; then
    log "package: legacy zip only (the extension is built with Blender 4.2+, from the Debian 13 chroot)"
    return
  fi
  local runner; runner="$(matrix_runner trixie)"
  $runner blender -b --factory-startup --command extension build --source-dir "$pkg" --output-dir "$dist" \
    >"$BUILD/extension-build.log" 2>&1 || { cat "$BUILD/extension-build.log" >&2; exit 1; }
  local ext; ext="$(ls "$dist"/myoskin-*.zip | grep -v -- -legacy.zip | head -1)"
  $runner blender -b --factory-startup --command extension validate "$ext" >>"$BUILD/extension-build.log" 2>&1 \
    || { cat "$BUILD/extension-build.log" >&2; echo "myoskin: extension validate failed" >&2; exit 1; }
  log "package: $ext (extension, Python $(cd "$pkg" && ls build_info-*.json | sed 's/build_info-\(.*\)\.json/\1/' | paste -sd' ')) and $dist/myoskin-$version-legacy.zip"
}
