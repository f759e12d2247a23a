#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `cmake --install` gives libraries a C programmer can link: the core
# (lodkit) with only its own dependencies, and the components lodkit-gl,
# lodkit-dem and lodkit-serve, through pkg-config (shared and --static) and
# through CMake's find_package, static and shared.
set -u
source "$(dirname "$0")/lib.sh"
: "${LK_BUILD_DIR:?}"
require cc gcc
require pkg-config pkg-config
prefix="$TMP/prefix"
check "cmake --install" cmake --install "$LK_BUILD_DIR" --prefix "$prefix" >/dev/null
libdir=$(dirname "$(dirname "$(find "$prefix" -name lodkit.pc | head -1)")")
export PKG_CONFIG_PATH="$libdir/pkgconfig"
export LD_LIBRARY_PATH="$libdir"

# The core needs none of the components' libraries, at run time or to build.
core_deps=$(ldd "$libdir/liblodkit.so")
for heavy in gdal EGL GLES png microhttpd; do
  check "liblodkit.so does not load $heavy" bash -c '! grep -qi -- "$1" <<<"$2"' _ "$heavy" "$core_deps"
done
check "lodkit.pc requires only libcjson and zlib" \
  test "$(pkg-config --print-requires --print-requires-private lodkit | sort | tr '\n' ' ')" = "libcjson zlib "
# GDAL is loaded when lodkit-dem first reads a grid through it (dlopen), not
# when a program using lodkit-dem starts: its libraries cost ~140 ms a process.
check "liblodkit-dem.so does not load gdal at start" bash -c '! ldd "$1" | grep -qi gdal' _ "$libdir/liblodkit-dem.so"
for component in gl dem serve; do
  check "lodkit-$component.pc installed" test -f "$libdir/pkgconfig/lodkit-$component.pc"
  check "liblodkit-$component.so uses liblodkit.so" bash -c 'ldd "$1" | grep -q "liblodkit.so"' _ \
    "$libdir/liblodkit-$component.so"
done

# A core program: shared, then the static archive with pkg-config --static.
cat > "$TMP/app.c" <<'C'
#include <lodkit.h>
#include <stdio.h>
int main(int argc, char **argv) {
    lk_mesh mesh; lk_error error = {0};
    if (argc < 2 || lk_mesh_read(argv[1], LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) { puts(error.message); return 1; }
    printf("%s %zu %zu\n", lk_version(), mesh.vertex_count, mesh.triangle_count);
    lk_mesh_free(&mesh);
    return 0;
}
C
check "pkg-config shared build" cc "$TMP/app.c" -o "$TMP/app" $(pkg-config --cflags --libs lodkit)
out=$("$TMP/app" "$LK_SAMPLES_DIR/cow.off")
check "shared app reads cow ($out)" grep -q "2904 5804" <<<"$out"
# --static: the archive by name and everything it needs from the .pc files alone.
static_libs=$(pkg-config --static --libs lodkit)
check "pkg-config --static lodkit ($static_libs)" test -n "$static_libs"
check "pkg-config static build" cc "$TMP/app.c" -o "$TMP/app_static" $(pkg-config --cflags lodkit) \
  -Wl,-Bstatic -llodkit -Wl,-Bdynamic $static_libs
check "static app does not load liblodkit.so" bash -c '! ldd "$1" | grep -q liblodkit' _ "$TMP/app_static"
out=$("$TMP/app_static" "$LK_SAMPLES_DIR/cow.off")
check "static app reads cow ($out)" grep -q "2904 5804" <<<"$out"

# A program of every component: a fractal grid rendered to PNG (gl), a grid
# read from a file (dem), a server started and stopped (serve).
cat > "$TMP/parts.c" <<'C'
#include <lodkit.h>
#include <stdio.h>
int main(int argc, char **argv) {
    lk_error error = {0};
    lk_heightfield field;
    if (argc < 3 || lk_dem_read(argv[1], NULL, &field, &error) != LK_OK) { puts(error.message); return 1; }
    printf("grid %zux%zu\n", field.width, field.height);
    lk_heightfield_free(&field);
    lk_server_options options;
    lk_server_options_default(&options);
    options.port = 0;
    lk_server *server = NULL;
    if (lk_server_start(argv[2], &options, &server, &error) != LK_OK) { puts(error.message); return 1; }
    lk_server_stop(server);
    puts("served");
    lk_renderer *renderer = NULL;
    if (lk_renderer_create(8, 8, &renderer, &error) != LK_OK) { puts(error.message); return 1; }
    lk_renderer_free(renderer);
    puts("rendered");
    return 0;
}
C
# netCDF: read through GDAL, which the library loads itself (no -lgdal below)
grid="$LK_SAMPLES_DIR/etopo20.cdf"
mkdir -p "$TMP/served"
check "pkg-config shared build of every component" cc "$TMP/parts.c" -o "$TMP/parts" \
  $(pkg-config --cflags --libs lodkit-gl lodkit-serve)
out=$("$TMP/parts" "$grid" "$TMP/served" 2>&1)
check "shared components work ($out)" grep -q "grid 1081x540.*rendered" <<<"$(tr '\n' ' ' <<<"$out")"
check "the shared program does not load gdal at start" bash -c '! ldd "$1" | grep -qi gdal' _ "$TMP/parts"
check "pkg-config static build of every component" cc "$TMP/parts.c" -o "$TMP/parts_static" \
  $(pkg-config --cflags lodkit-gl lodkit-serve) \
  -Wl,-Bstatic -llodkit-serve -llodkit-dem -llodkit-gl -llodkit -Wl,-Bdynamic \
  $(pkg-config --static --libs lodkit-gl lodkit-serve)
out=$("$TMP/parts_static" "$grid" "$TMP/served" 2>&1)
check "static components work ($out)" grep -q "grid 1081x540.*rendered" <<<"$(tr '\n' ' ' <<<"$out")"

# CMake: find_package(lodkit) with and without COMPONENTS, shared and static.
for variant in shared static; do
  suffix=""; [ "$variant" = static ] && suffix="_static"
  app="$TMP/cmake-$variant"
  mkdir -p "$app"
  cp "$TMP/app.c" "$TMP/parts.c" "$app/"
  cat > "$app/CMakeLists.txt" <<CM
cmake_minimum_required(VERSION 3.22)
project(app C)
find_package(lodkit REQUIRED)
add_executable(app app.c)
target_link_libraries(app PRIVATE lodkit::lodkit$suffix)
find_package(lodkit REQUIRED COMPONENTS gl serve)
add_executable(parts parts.c)
target_link_libraries(parts PRIVATE lodkit::gl$suffix lodkit::serve$suffix)
CM
  check "find_package(lodkit) $variant" cmake -S "$app" -B "$app/build" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
  check "cmake app builds ($variant)" cmake --build "$app/build" >/dev/null
  out=$("$app/build/app" "$LK_SAMPLES_DIR/cow.off")
  check "cmake app reads cow ($variant: $out)" grep -q "2904 5804" <<<"$out"
  out=$("$app/build/parts" "$grid" "$TMP/served" 2>&1)
  check "cmake components work ($variant: $out)" grep -q "rendered" <<<"$out"
done
app="$TMP/cmake-missing"
mkdir -p "$app"
printf 'cmake_minimum_required(VERSION 3.22)\nproject(app C)\nfind_package(lodkit REQUIRED COMPONENTS vr)\n' >"$app/CMakeLists.txt"
expect_exit 1 cmake -S "$app" -B "$app/build" -DCMAKE_PREFIX_PATH="$prefix"
finish
