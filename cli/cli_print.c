/* SPDX-License-Identifier: MIT */
/* Printing results: numbers with thousands separators, counts with their
 * noun, JSON on one line. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

/* The rotating buffers of thousands and count_noun. */
static char *next_slot(void)
{
    static char slots[8][64];
    static int next;
    char *slot = slots[next];
    next = (next + 1) % 8;
    return slot;
}

static void with_separators(unsigned long long value, char *out)
{
    char digits[32];
    int length = snprintf(digits, sizeof digits, "%llu", value);
    int o = 0;
    for (int i = 0; i < length; i++) {
        if (i > 0 && (length - i) % 3 == 0) out[o++] = ',';
        out[o++] = digits[i];
    }
    out[o] = '\0';
}

/* 1234567 -> "1,234,567" in a rotating static buffer. */
const char *thousands(unsigned long long value)
{
    char *out = next_slot();
    with_separators(value, out);
    return out;
}

const char *count_noun(unsigned long long value, const char *one, const char *many)
{
    char *out = next_slot(), number[32];
    with_separators(value, number);
    snprintf(out, 64, "%s %s", number, value == 1 ? one : many);
    return out;
}

const char *n_vertices(unsigned long long value) { return count_noun(value, "vertex", "vertices"); }

const char *n_triangles(unsigned long long value) { return count_noun(value, "triangle", "triangles"); }

void print_json(cJSON *root)
{
    char *text = cJSON_PrintUnformatted(root);
    if (text) {
        puts(text);
        free(text);
    }
    cJSON_Delete(root);
}

cJSON *distance_json(const lk_distance_stats *stats)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddNumberToObject(object, "max", stats->max);
    cJSON_AddNumberToObject(object, "mean", stats->mean);
    cJSON_AddNumberToObject(object, "rms", stats->rms);
    cJSON_AddNumberToObject(object, "samples", (double)stats->sample_count);
    return object;
}
