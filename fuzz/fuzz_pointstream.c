/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the point octree's streamed inputs (src/octree_input.c:
 * XYZ, ASCII PLY and ascii PCD line by line, binary PLY, binary PCD and LAS
 * record by record). The first byte picks the file's kind (0: .xyz, 1: .ply,
 * 2: .las, 3: .pcd; others: by its remainder), the rest is the file, written to a temporary file and read
 * batch by batch as the octree's passes read it. Any input must end in an
 * error with a message, or in batches of finite points whose total is the
 * source's count. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "octree_internal.h"

static char folder[64];
static ot_batch batch;
static const char *const names[4] = {"in.xyz", "in.ply", "in.las", "in.pcd"};

/* The folder is made on the first input and removed when the process ends
 * (libFuzzer returns from main or calls exit), so that the CTest smoke
 * runs leave nothing in /tmp. */
static void remove_folder(void)
{
    char path[128];
    for (int i = 0; i < 4; i++) {
        snprintf(path, sizeof path, "%s/%s", folder, names[i]);
        unlink(path);
    }
    rmdir(folder);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    if (!folder[0]) {
        snprintf(folder, sizeof folder, "/tmp/lodkit-fuzz-points-XXXXXX");
        if (!mkdtemp(folder)) abort();
        atexit(remove_folder);
    }
    char path[128];
    snprintf(path, sizeof path, "%s/%s", folder, names[data[0] % 4]);
    FILE *file = fopen(path, "wb");
    if (!file) abort();
    if (size > 1 && fwrite(data + 1, 1, size - 1, file) != size - 1) abort();
    fclose(file);
    ot_source source;
    memset(&source, 0, sizeof source);
    source.max_read_bytes = 1 << 20;
    lk_error error = {0};
    lk_status status = lk__octree_source_open(&source, path, &error);
    unsigned long long total = 0;
    while (status == LK_OK && source.next < source.count) {
        status = lk__octree_source_next(&source, &batch, &error);
        if (status != LK_OK) break;
        if (batch.count > OT_BATCH) abort();
        for (size_t i = 0; i < 3 * batch.count; i++)
            if (!isfinite(batch.xyz[i])) abort();
        total += batch.count;
    }
    if (status != LK_OK && error.message[0] == '\0') abort();
    if (status == LK_OK && (total != source.count || total == 0)) abort();
    lk__octree_source_close(&source);
    unlink(path);
    return 0;
}
