/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the glTF scene reader (src/io_gltf_scene.c,
 * lk_scene_read_memory): any input gives either a scene whose references
 * are all in range, whose primitives are valid meshes and which flattens,
 * or an error with a message and an empty scene; never a crash or leak. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "lodkit.h"
#include "scene_check.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    lk_scene scene;
    lk_error error = {0};
    lk_read_options options = {.max_bytes = (size_t)64 << 20};
    /* The first byte picks the container: .glb or .gltf (JSON). */
    const char *name = size > 0 && data[0] == 'g' ? "fuzz.glb" : "fuzz.gltf";
    lk_status status = lk_scene_read_memory(data, size, name, &options, &scene, &error);
    if (status == LK_OK)
        check_scene(&scene);
    else if (error.message[0] == '\0' || scene.node_count != 0 || scene.nodes != NULL)
        abort();
    lk_scene_free(&scene);
    return 0;
}
