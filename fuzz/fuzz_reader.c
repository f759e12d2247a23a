/* SPDX-License-Identifier: MIT */
/* libFuzzer target for one mesh reader: LK_FUZZ_FORMAT selects the format
 * (compiled once per format by fuzz/CMakeLists.txt). Any input must give
 * either a valid mesh or an error with a message; never a crash or leak. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "lodkit.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    lk_mesh mesh;
    lk_error error = {0};
    /* A small budget keeps every input fast: huge claims must be refused. */
    lk_read_options options = {.max_bytes = (size_t)64 << 20};
    lk_status status = lk_mesh_read_memory(data, size, LK_FUZZ_NAME, LK_FUZZ_FORMAT, &options, &mesh, &error);
    if (status == LK_OK) {
        if (lk_mesh_validate(&mesh, NULL) != LK_OK) abort();
        lk_mesh_stats stats;
        if (lk_mesh_compute_stats(&mesh, &stats, NULL) != LK_OK) abort();
    } else {
        if (error.message[0] == '\0' || mesh.vertex_count != 0 || mesh.positions != NULL) abort();
    }
    lk_mesh_free(&mesh);
    return 0;
}
