/* SPDX-License-Identifier: MIT */
/* The ABI rule for option structs (top of include/lodkit.h, docs/api.md):
 * every lk_*_options struct ends in zeroed `reserved` words and keeps its
 * size, so a field added later takes reserved words instead of growing the
 * struct; and every lk_*_options_default zeroes those words. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "testutil.h"

typedef struct struct_layout {
    const char *name;
    size_t size;
    size_t reserved_offset;
    size_t reserved_size;
    size_t size_lp64; /* the size programs built against 0.1 allocate */
} struct_layout;

#define LAYOUT(type, size_lp64)                                                                                        \
    {                                                                                                                  \
#type, sizeof(type), offsetof(type, reserved), sizeof(((type *)0)->reserved), size_lp64                        \
    }

static const struct_layout layouts[] = {
    LAYOUT(lk_read_options, 72),
    LAYOUT(lk_write_options, 88),
    LAYOUT(lk_metro_options, 104),
    LAYOUT(lk_simplify_options, 152),
    LAYOUT(lk_contour_simplify_options, 88),
    LAYOUT(lk_animation_read_options, 104),
    LAYOUT(lk_anim_simplify_options, 256),
    LAYOUT(lk_progressive_options, 232),
    LAYOUT(lk_stream_options, 88),
    LAYOUT(lk_sample_options, 104),
    LAYOUT(lk_render_options, 200),
    LAYOUT(lk_dem_options, 120),
    LAYOUT(lk_terrain_options, 112),
    LAYOUT(lk_server_options, 192),
    LAYOUT(lk_octree_select_options, 80), /* new in issue 23 */
};

/* `reserved` is the last member, and the size is the one 0.1 shipped: a
 * field inserted or appended without taking reserved words fails here. */
static void test_option_struct_layout(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof layouts / sizeof layouts[0]; i++) {
        const struct_layout *layout = &layouts[i];
        if (layout->reserved_offset + layout->reserved_size != layout->size)
            fail_msg("%s: `reserved` is not its last member", layout->name);
        if (sizeof(void *) == 8 && sizeof(size_t) == 8 && layout->size != layout->size_lp64)
            fail_msg("%s: %zu bytes, but programs built against 0.1 allocate %zu: new fields must take "
                     "`reserved` words",
                     layout->name, layout->size, layout->size_lp64);
    }
}

static int all_zero(const void *bytes, size_t size)
{
    const unsigned char *byte = bytes;
    for (size_t i = 0; i < size; i++)
        if (byte[i]) return 0;
    return 1;
}

/* Fills `options` with garbage (a caller's uninitialised stack), runs the
 * defaults function on it and checks that its reserved words are zero. */
#define DEFAULTS_FROM_GARBAGE(options, function)                                                                       \
    do {                                                                                                               \
        memset(&(options), 0xA5, sizeof(options));                                                                     \
        function(&(options));                                                                                          \
        if (!all_zero((options).reserved, sizeof(options).reserved))                                                   \
            fail_msg(#function " leaves reserved words non-zero");                                                     \
    } while (0)

static void test_defaults_zero_reserved(void **state)
{
    (void)state;
    lk_metro_options metro;
    DEFAULTS_FROM_GARBAGE(metro, lk_metro_options_default);
    lk_simplify_options simplify;
    DEFAULTS_FROM_GARBAGE(simplify, lk_simplify_options_default);
    lk_anim_simplify_options anim;
    DEFAULTS_FROM_GARBAGE(anim, lk_anim_simplify_options_default);
    assert_true(all_zero(anim.simplify.reserved, sizeof anim.simplify.reserved));
    lk_progressive_options progressive;
    DEFAULTS_FROM_GARBAGE(progressive, lk_progressive_options_default);
    assert_true(all_zero(progressive.simplify.reserved, sizeof progressive.simplify.reserved));
    lk_stream_options stream;
    DEFAULTS_FROM_GARBAGE(stream, lk_stream_options_default);
    lk_sample_options sample;
    DEFAULTS_FROM_GARBAGE(sample, lk_sample_options_default);
    lk_render_options render;
    DEFAULTS_FROM_GARBAGE(render, lk_render_options_default);
    lk_dem_options dem;
    DEFAULTS_FROM_GARBAGE(dem, lk_dem_options_default);
    lk_terrain_options terrain;
    DEFAULTS_FROM_GARBAGE(terrain, lk_terrain_options_default);
    lk_server_options server;
    DEFAULTS_FROM_GARBAGE(server, lk_server_options_default);
    lk_octree_select_options select;
    DEFAULTS_FROM_GARBAGE(select, lk_octree_select_options_default);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_option_struct_layout),
        cmocka_unit_test(test_defaults_zero_reserved),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
