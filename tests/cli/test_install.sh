#!/usr/bin/env bash
# `cmake --install` gives a library a C programmer can link: through
# pkg-config and through CMake's find_package, static and shared.
set -u
source "$(dirname "$0")/lib.sh"
: "${LK_BUILD_DIR:?}"
prefix="$TMP/prefix"
check "cmake --install" cmake --install "$LK_BUILD_DIR" --prefix "$prefix" >/dev/null
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
libdir=$(dirname "$(find "$prefix" -name lodkit.pc | head -1)")
export PKG_CONFIG_PATH="$libdir"
check "pkg-config shared build" cc "$TMP/app.c" -o "$TMP/app" $(pkg-config --cflags --libs lodkit)
out=$(LD_LIBRARY_PATH="$prefix/lib:$(dirname "$libdir")" "$TMP/app" "$LK_SAMPLES_DIR/cow.off")
check "shared app reads cow ($out)" grep -q "2904 5804" <<<"$out"
check "pkg-config static build" cc "$TMP/app.c" -o "$TMP/app_static" $(pkg-config --cflags lodkit) \
  "$(dirname "$libdir")/liblodkit.a" $(pkg-config --libs-only-l --static libcjson) -lcjson -lpthread -lm
out=$("$TMP/app_static" "$LK_SAMPLES_DIR/cow.off")
check "static app reads cow ($out)" grep -q "2904 5804" <<<"$out"
mkdir -p "$TMP/cmake-app"
cp "$TMP/app.c" "$TMP/cmake-app/"
cat > "$TMP/cmake-app/CMakeLists.txt" <<'CM'
cmake_minimum_required(VERSION 3.22)
project(app C)
find_package(lodkit REQUIRED)
add_executable(app app.c)
target_link_libraries(app PRIVATE lodkit::lodkit)
CM
check "find_package(lodkit)" cmake -S "$TMP/cmake-app" -B "$TMP/cmake-app/build" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
check "cmake app builds" cmake --build "$TMP/cmake-app/build" >/dev/null
out=$("$TMP/cmake-app/build/app" "$LK_SAMPLES_DIR/cow.off")
check "cmake app reads cow ($out)" grep -q "2904 5804" <<<"$out"
finish
