/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the OBJ scene reader (src/io_obj_scene.c): an input
 * is an .obj read with lk_scene_read_memory, or, when it holds a line
 * "#mtl", the .obj before that line with the text after it read as every
 * .mtl the .obj names (lk__read_obj_scene_text), so that the .mtl parser
 * is fuzzed too. Either a scene that passes scene_check.h or an error with
 * a message and an empty scene; never a crash or leak. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "lodkit.h"
#include "scene_check.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char marker[] = "\n#mtl\n";
    const char *text = (const char *)data;
    const char *split = NULL;
    for (size_t i = 0; i + sizeof marker - 1 <= size && !split; i++)
        if (memcmp(text + i, marker, sizeof marker - 1) == 0) split = text + i;
    lk_scene scene;
    lk_error error = {0};
    lk_status status;
    size_t limit = (size_t)64 << 20;
    if (split) {
        size_t obj_size = (size_t)(split - text) + 1; /* with its last newline */
        const char *mtl = split + sizeof marker - 1;
        lk__budget budget = {limit, 0};
        lk__budget_charge(&budget, size, 1);
        lk__read_context ctx = {"fuzz.obj", NULL, &budget};
        status = lk__read_obj_scene_text(text, obj_size, mtl, (size_t)(text + size - mtl), &ctx, &scene, &error);
    } else {
        lk_read_options options = {.max_bytes = limit};
        status = lk_scene_read_memory(data, size, "fuzz.obj", &options, &scene, &error);
    }
    if (status == LK_OK)
        check_scene(&scene);
    else if (error.message[0] == '\0' || scene.node_count != 0 || scene.nodes != NULL)
        abort();
    lk_scene_free(&scene);
    return 0;
}
