/* SPDX-License-Identifier: MIT */
/* Point octrees (src/octree.c) on real clouds: Haystack_Rock.las (streamed
 * LAS, georeferenced), kitten.xyz (normals), the PCD samples (colours).
 * Every octree built is read back whole and checked against the input:
 * each input point in exactly one node at its quantised position, each
 * node's points inside its cube, the points of a node that has children
 * at least the level's spacing apart; and the build does not depend on the
 * thread count or on how many chunks the points were spilled to. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testutil.h"

#include "bytes.h"
#include "internal.h"

/* The input's positions in double, as the octree reads them. */
typedef struct cloud {
    size_t count;
    double *xyz;
    int has_colors;
    float *colors; /* 4 per point, or NULL */
} cloud;

static void read_las_doubles(const char *path, cloud *c)
{
    size_t size;
    unsigned char *data = lk_test_read_file(path, &size);
    lk__las_header header;
    lk_error error = {0};
    assert_int_equal(lk__las_parse_header(data, size, path, &header, &error), LK_OK);
    c->count = (size_t)header.point_count;
    c->xyz = malloc(3 * c->count * sizeof(double));
    assert_non_null(c->xyz);
    for (size_t i = 0; i < c->count; i++) {
        const unsigned char *record = data + header.point_offset + i * header.record_length;
        for (int k = 0; k < 3; k++)
            c->xyz[3 * i + (size_t)k] = lk__load_i32le(record + 4 * k) * header.scale[k] + header.offset[k];
    }
    c->colors = NULL;
    free(data);
}

/* An XYZ file's points as doubles, read with strtod (an oracle independent
 * of lodkit's parser): the octree streams XYZ in double, as LAS. */
static void read_xyz_doubles(const char *path, cloud *c)
{
    size_t size;
    char *text = (char *)lk_test_read_file(path, &size);
    text[size] = '\0'; /* room was left for it */
    size_t capacity = 1024;
    c->xyz = malloc(3 * capacity * sizeof(double));
    assert_non_null(c->xyz);
    c->count = 0;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        double v[3];
        if (line[strspn(line, " \t\r")] == '#' || sscanf(line, "%lf %lf %lf", &v[0], &v[1], &v[2]) != 3) continue;
        if (c->count == capacity) {
            capacity *= 2;
            c->xyz = realloc(c->xyz, 3 * capacity * sizeof(double));
            assert_non_null(c->xyz);
        }
        memcpy(c->xyz + 3 * c->count++, v, sizeof v);
    }
    free(text);
}

static void read_cloud(const char *path, cloud *c)
{
    memset(c, 0, sizeof *c);
    size_t length = strlen(path);
    if (length > 4 && strcmp(path + length - 4, ".las") == 0) {
        read_las_doubles(path, c);
        return;
    }
    if (length > 4 && strcmp(path + length - 4, ".xyz") == 0) {
        read_xyz_doubles(path, c);
        return;
    }
    lk_mesh mesh;
    lk_test_load(path, &mesh);
    c->count = mesh.vertex_count;
    c->xyz = malloc(3 * c->count * sizeof(double));
    assert_non_null(c->xyz);
    for (size_t i = 0; i < 3 * c->count; i++) c->xyz[i] = mesh.positions[i];
    if (mesh.colors) {
        c->colors = mesh.colors;
        mesh.colors = NULL;
    }
    lk_mesh_free(&mesh);
}

static void free_cloud(cloud *c)
{
    free(c->xyz);
    free(c->colors);
}

static int compare_triples(const void *a, const void *b)
{
    const int32_t *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}

static int compare_by_x(const void *a, const void *b)
{
    const int32_t *x = a, *y = b;
    return (x[0] > y[0]) - (x[0] < y[0]);
}

static int has_children(const lk_octree *octree, const lk_octree_node *node)
{
    size_t length = strlen(node->name);
    for (size_t i = 0; i < lk_octree_get_info(octree)->node_count; i++) {
        const lk_octree_node *other = lk_octree_node_at(octree, i);
        if (strlen(other->name) == length + 1 && strncmp(other->name, node->name, length) == 0) return 1;
    }
    return 0;
}

/* Smallest distance (in quantisation steps) between two of the points, by
 * a sweep along x; stops early below `floor`. */
static double min_distance(int32_t *q, size_t n, double floor_distance)
{
    qsort(q, n, 3 * sizeof(int32_t), compare_by_x);
    double best = INFINITY;
    for (size_t i = 0; i < n; i++)
        for (size_t j = i + 1; j < n && (double)q[3 * j] - q[3 * i] < best; j++) {
            double dx = (double)q[3 * j] - q[3 * i], dy = (double)q[3 * j + 1] - q[3 * i + 1],
                   dz = (double)q[3 * j + 2] - q[3 * i + 2];
            double d = sqrt(dx * dx + dy * dy + dz * dz);
            if (d < best) best = d;
            if (best < floor_distance) return best;
        }
    return best;
}

/* Reads every node back and checks it against the input. */
static void check_octree(const char *dir, const cloud *input)
{
    lk_octree *octree;
    lk_error error = {0};
    lk_status status = lk_octree_open(dir, &octree, &error);
    if (status != LK_OK) fprintf(stderr, "%s\n", error.message);
    assert_int_equal(status, LK_OK);
    const lk_octree_info *info = lk_octree_get_info(octree);
    assert_int_equal(info->points, input->count);
    int32_t *all = malloc(3 * input->count * sizeof(int32_t));
    assert_non_null(all);
    size_t total = 0;
    double steps = info->cube_size / info->scale[0]; /* the cube's side in steps, a power of two */
    for (size_t i = 0; i < info->node_count; i++) {
        const lk_octree_node *node = lk_octree_node_at(octree, i);
        int32_t *q;
        size_t n;
        status = lk_octree_load_node_quantized(octree, i, &q, &n, &error);
        if (status != LK_OK) fprintf(stderr, "%s\n", error.message);
        assert_int_equal(status, LK_OK);
        assert_int_equal(n, node->points);
        assert_true(total + n <= input->count);
        /* inside the node's cube, in exact integer steps */
        double side = steps / (double)(1u << node->level);
        double lo[3];
        for (int k = 0; k < 3; k++) lo[k] = (node->min[k] - info->offset[k]) / info->scale[k];
        for (size_t p = 0; p < n; p++)
            for (int k = 0; k < 3; k++) {
                double v = q[3 * p + (size_t)k];
                assert_true(v >= floor(lo[k] + 0.5) && v < floor(lo[k] + 0.5) + side);
            }
        /* a node with children holds a Poisson-disk sample at its spacing */
        if (n > 1 && has_children(octree, node)) {
            double spacing = info->spacing / info->scale[0] / (double)(1u << node->level);
            double d = min_distance(q, n, spacing);
            if (d < spacing) fprintf(stderr, "node %s: points %g apart, spacing %g\n", node->name, d, spacing);
            assert_true(d >= spacing);
        }
        /* radii: positive, finite */
        lk_mesh mesh;
        assert_int_equal(lk_octree_load_node(octree, i, &mesh, &error), LK_OK);
        for (size_t p = 0; p < n; p++) assert_true(mesh.radii[p] > 0 && isfinite(mesh.radii[p]));
        lk_mesh_free(&mesh);
        memcpy(all + 3 * total, q, 3 * n * sizeof(int32_t));
        total += n;
        lk_free(q);
    }
    assert_int_equal(total, input->count);
    /* the same points: the input quantised as the octree says, matched sorted */
    int32_t *expected = malloc(3 * input->count * sizeof(int32_t));
    assert_non_null(expected);
    for (size_t p = 0; p < input->count; p++)
        for (int k = 0; k < 3; k++) {
            double steps_here = floor((input->xyz[3 * p + (size_t)k] - info->offset[k]) / info->scale[k] + 0.5);
            expected[3 * p + (size_t)k] = (int32_t)steps_here;
            /* and within half a step of the input */
            double back = info->offset[k] + steps_here * info->scale[k];
            assert_true(fabs(back - input->xyz[3 * p + (size_t)k]) <= 0.5 * info->scale[k] * (1 + 1e-6) + 1e-9);
        }
    qsort(all, input->count, 3 * sizeof(int32_t), compare_triples);
    qsort(expected, input->count, 3 * sizeof(int32_t), compare_triples);
    assert_memory_equal(all, expected, 3 * input->count * sizeof(int32_t));
    free(all);
    free(expected);
    lk_octree_close(octree);
}

static void build(const char *input, const char *dir, const lk_octree_options *options, lk_octree_stats *stats)
{
    lk_error error = {0};
    const char *inputs[1] = {input};
    lk_status status = lk_octree_build(inputs, 1, dir, options, stats, NULL, NULL, &error);
    if (status != LK_OK) fprintf(stderr, "%s\n", error.message);
    assert_int_equal(status, LK_OK);
}

static void assert_same_file(const char *a, const char *b)
{
    size_t size_a, size_b;
    unsigned char *x = lk_test_read_file(a, &size_a), *y = lk_test_read_file(b, &size_b);
    assert_int_equal(size_a, size_b);
    assert_memory_equal(x, y, size_a);
    free(x);
    free(y);
}

/* The two octrees are the same bytes, data and index. */
static void assert_same_octree(const char *a, const char *b)
{
    assert_same_file(lk_test_path(a, "octree.bin"), lk_test_path(b, "octree.bin"));
    assert_same_file(lk_test_path(a, "octree.json"), lk_test_path(b, "octree.json"));
}

/* Reads a sample into c, its path into path, and the default options. */
static void sample_with_defaults(const char *name, char path[1024], cloud *c, lk_octree_options *options)
{
    snprintf(path, 1024, "%s", lk_test_sample(name));
    read_cloud(path, c);
    lk_octree_options_default(options);
}

static void test_las_chunks_and_threads(void **state)
{
    (void)state;
    const char *input = lk_test_sample("las/Haystack_Rock.las");
    char path[1024];
    snprintf(path, sizeof path, "%s", input);
    cloud c;
    read_cloud(path, &c);
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 500;
    /* one chunk */
    lk_octree_stats one;
    char dir_one[1024], dir_many1[1024], dir_many2[1024];
    snprintf(dir_one, sizeof dir_one, "%s", lk_test_tmpfile("rock_one"));
    snprintf(dir_many1, sizeof dir_many1, "%s", lk_test_tmpfile("rock_many1"));
    snprintf(dir_many2, sizeof dir_many2, "%s", lk_test_tmpfile("rock_many2"));
    build(path, dir_one, &options, &one);
    assert_int_equal(one.chunks, 1);
    assert_int_equal(one.points, c.count);
    check_octree(dir_one, &c);
    /* many chunks (spilled apart, built one by one), 1 and 2 threads */
    options.chunk_points = 1000;
    options.threads = 1;
    lk_octree_stats many1, many2;
    build(path, dir_many1, &options, &many1);
    assert_true(many1.chunks > 10);
    assert_true(many1.temp_bytes >= 20 * c.count);
    check_octree(dir_many1, &c);
    options.threads = 2;
    build(path, dir_many2, &options, &many2);
    assert_int_equal(many2.chunks, many1.chunks);
    assert_same_octree(dir_many1, dir_many2);
    /* no spill files left behind */
    assert_int_equal(access(lk_test_path(dir_many1, "octree.bin"), F_OK), 0);
    free_cloud(&c);
}

static void test_kitten_normals(void **state)
{
    (void)state;
    char path[1024];
    cloud c;
    lk_octree_options options;
    sample_with_defaults("kitten.xyz", path, &c, &options);
    options.max_node_points = 300;
    options.chunk_points = 800;
    char dir[1024];
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("kitten"));
    build(path, dir, &options, NULL);
    check_octree(dir, &c);
    /* the file's normals are kept: unit length, and the reader decodes them */
    lk_octree *octree;
    lk_error error = {0};
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    assert_true(lk_octree_get_info(octree)->has_normals);
    assert_false(lk_octree_get_info(octree)->has_colors);
    lk_mesh node;
    assert_int_equal(lk_octree_load_node(octree, 0, &node, &error), LK_OK);
    assert_non_null(node.normals);
    for (size_t i = 0; i < node.vertex_count; i++) {
        const float *n = node.normals + 3 * i;
        assert_true(fabsf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0f) < 1e-3f);
    }
    lk_mesh_free(&node);
    /* a fine spacing: more cells a side than the dense grid holds (the hashed grid) */
    lk_octree_options fine = options;
    fine.spacing = lk_octree_get_info(octree)->cube_size / 1000.0;
    lk_octree_close(octree);
    build(path, dir, &fine, NULL);
    check_octree(dir, &c);
    /* estimated normals */
    options.normals = LK_OCTREE_NORMALS_ESTIMATE;
    build(path, dir, &options, NULL);
    check_octree(dir, &c);
    free_cloud(&c);
}

/* The default root spacing and leaf size adapt to the cloud: kitten.xyz
 * (5,210 points, 0.03 apart in a cube of side 1.07) kept every point in
 * the root at side / 128 and a leaf size of 20,000 (one level); now its
 * root holds a subsample of at most an eighth and it gets levels below, for
 * 1 and 2 threads alike; an explicit spacing and leaf size still rule. */
static void test_small_cloud_levels(void **state)
{
    (void)state;
    char path[1024];
    cloud c;
    lk_octree_options options;
    sample_with_defaults("kitten.xyz", path, &c, &options);
    assert_int_equal(options.max_node_points, 0);
    assert_true(options.spacing == 0.0);
    options.chunk_points = 1500; /* several chunks, so that threads build some at once */
    char dir1[1024], dir2[1024];
    snprintf(dir1, sizeof dir1, "%s", lk_test_tmpfile("kitten_auto1"));
    snprintf(dir2, sizeof dir2, "%s", lk_test_tmpfile("kitten_auto2"));
    lk_octree_stats stats1, stats2;
    options.threads = 1;
    build(path, dir1, &options, &stats1);
    options.threads = 2;
    build(path, dir2, &options, &stats2);
    check_octree(dir1, &c);
    assert_same_octree(dir1, dir2);
    lk_octree *octree;
    lk_error error = {0};
    assert_int_equal(lk_octree_open(dir1, &octree, &error), LK_OK);
    const lk_octree_info *info = lk_octree_get_info(octree);
    const lk_octree_node *root = lk_octree_node_at(octree, 0);
    print_message("kitten: %u levels, %zu nodes, root %llu of %llu points, spacing %g (cube %g)\n", stats1.levels,
                  stats1.nodes, (unsigned long long)root->points, (unsigned long long)info->points, info->spacing,
                  info->cube_size);
    /* measured: 3 levels, 23 nodes, root 205 points at side / 16 (236 in one chunk) */
    assert_string_equal(root->name, "r");
    assert_true(stats1.levels >= 2);
    assert_true(root->points > 0 && root->points <= c.count / 8);
    assert_true(info->spacing > info->cube_size / 128);
    lk_octree_close(octree);

    /* explicit options: side / 128 and a leaf of 20,000, the old defaults, keep
     * the whole kitten in the root */
    options.max_node_points = 20000;
    options.chunk_points = 2000000;
    options.spacing = 1.073741824 / 128;
    build(path, dir1, &options, &stats1);
    assert_int_equal(stats1.levels, 1);
    assert_int_equal(lk_octree_open(dir1, &octree, &error), LK_OK);
    assert_true(lk_octree_get_info(octree)->spacing == options.spacing);
    assert_int_equal(lk_octree_node_at(octree, 0)->points, c.count);
    lk_octree_close(octree);
    free_cloud(&c);
}

static void test_pcd_colours(void **state)
{
    (void)state;
    static const char *const names[] = {"pcd/milk.pcd", "pcd/bun0.pcd", "pcd/test_pcd.pcd"};
    for (size_t f = 0; f < sizeof names / sizeof names[0]; f++) {
        char path[1024];
        snprintf(path, sizeof path, "%s", lk_test_sample(names[f]));
        cloud c;
        read_cloud(path, &c);
        lk_octree_options options;
        lk_octree_options_default(&options);
        options.max_node_points = 2000;
        options.chunk_points = 5000;
        char dir[1024];
        snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("pcd"));
        build(path, dir, &options, NULL);
        check_octree(dir, &c);
        lk_octree *octree;
        lk_error error = {0};
        assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
        assert_int_equal(lk_octree_get_info(octree)->has_colors, c.colors != NULL);
        if (c.colors) {
            /* the colours' sum over every node is the input's, to 8 bits */
            double sum_in = 0, sum_out = 0;
            for (size_t i = 0; i < c.count; i++) sum_in += floor(c.colors[4 * i] * 255.0f + 0.5f);
            for (size_t i = 0; i < lk_octree_get_info(octree)->node_count; i++) {
                lk_mesh node;
                assert_int_equal(lk_octree_load_node(octree, i, &node, &error), LK_OK);
                for (size_t p = 0; p < node.vertex_count; p++) sum_out += floor(node.colors[4 * p] * 255.0f + 0.5f);
                lk_mesh_free(&node);
            }
            assert_true(sum_in == sum_out);
        }
        lk_octree_close(octree);
        free_cloud(&c);
    }
}

/* PLY is streamed (binary little- and big-endian, and ASCII, whose float
 * properties are rounded to float as they are declared): the same octree
 * from all three; a cut binary PLY is refused. */
static void test_ply_streamed(void **state)
{
    (void)state;
    char xyz[1024];
    snprintf(xyz, sizeof xyz, "%s", lk_test_sample("pcd/milk.pcd"));
    lk_mesh mesh;
    lk_test_load(xyz, &mesh);
    static const lk_ply_encoding encodings[3] = {LK_PLY_BINARY_LE, LK_PLY_BINARY_BE, LK_PLY_ASCII};
    char ply[3][1024], dir[3][1024];
    lk_error error = {0};
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 1000;
    options.chunk_points = 4000;
    for (int e = 0; e < 3; e++) {
        snprintf(ply[e], sizeof ply[e], "%s",
                 lk_test_tmpfile(e == 0   ? "milk_le.ply"
                                 : e == 1 ? "milk_be.ply"
                                          : "milk_a.ply"));
        snprintf(dir[e], sizeof dir[e], "%s", lk_test_tmpfile(e == 0 ? "milk_le" : e == 1 ? "milk_be" : "milk_a"));
        lk_write_options write;
        memset(&write, 0, sizeof write);
        write.ply_encoding = encodings[e];
        assert_int_equal(lk_mesh_write(ply[e], LK_FORMAT_PLY, &mesh, &write, &error), LK_OK);
        build(ply[e], dir[e], &options, NULL);
    }
    cloud c;
    read_cloud(ply[0], &c);
    check_octree(dir[0], &c);
    free_cloud(&c);
    for (int e = 1; e < 3; e++) {
        assert_same_octree(dir[0], dir[e]);
    }
    /* cut in the middle of the vertices: refused before anything is written */
    struct stat info;
    assert_int_equal(stat(ply[0], &info), 0);
    assert_int_equal(truncate(ply[0], info.st_size / 2), 0);
    const char *inputs[1] = {ply[0]};
    char cut_dir[1024];
    snprintf(cut_dir, sizeof cut_dir, "%s", lk_test_tmpfile("milk_cut"));
    assert_int_equal(lk_octree_build(inputs, 1, cut_dir, &options, NULL, NULL, NULL, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "milk_le.ply:"));
    assert_non_null(strstr(error.message, "do not fit in the")); /* the streaming reader's words */
    assert_int_not_equal(access(cut_dir, F_OK), 0);
    lk_mesh_free(&mesh);
}

/* Binary PCD is streamed record by record: the points of milk.pcd written
 * as a binary PCD with a NaN point among them (dropped, as the whole-file
 * reader drops it) give the octree of those points, colours included; a
 * cut file is refused with its byte offset. */
static void test_pcd_streamed(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("pcd/milk.pcd"), &mesh);
    assert_non_null(mesh.colors);
    char path[1024], dir[1024];
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("milk_binary.pcd"));
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("milk_binary"));
    FILE *file = fopen(path, "wb");
    assert_non_null(file);
    size_t n = mesh.vertex_count;
    fprintf(file,
            "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
            "WIDTH %zu\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %zu\nDATA binary\n",
            n + 1, n + 1);
    for (size_t i = 0; i <= n; i++) {
        size_t v = i < n / 2 ? i : i - 1; /* record n / 2 is the NaN point */
        float xyz[3] = {mesh.positions[3 * v], mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]};
        if (i == n / 2) xyz[1] = NAN;
        uint32_t rgb = 0;
        for (int k = 0; k < 3; k++) rgb = rgb << 8 | (uint32_t)floorf(mesh.colors[4 * v + (size_t)k] * 255.0f + 0.5f);
        assert_int_equal(fwrite(xyz, sizeof xyz, 1, file), 1);
        assert_int_equal(fwrite(&rgb, sizeof rgb, 1, file), 1);
    }
    fclose(file);
    cloud c;
    c.count = n;
    c.xyz = malloc(3 * n * sizeof(double));
    assert_non_null(c.xyz);
    for (size_t i = 0; i < 3 * n; i++) c.xyz[i] = mesh.positions[i];
    c.colors = NULL;
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 1000;
    options.chunk_points = 4000;
    options.max_read_bytes = 4096; /* streamed: a read of the whole file would be refused */
    build(path, dir, &options, NULL);
    check_octree(dir, &c);
    /* the colours' sum over every node is the input's */
    lk_octree *octree;
    lk_error error = {0};
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    assert_true(lk_octree_get_info(octree)->has_colors);
    double sum_in = 0, sum_out = 0;
    for (size_t i = 0; i < n; i++) sum_in += floor(mesh.colors[4 * i + 1] * 255.0f + 0.5f);
    for (size_t i = 0; i < lk_octree_get_info(octree)->node_count; i++) {
        lk_mesh node;
        assert_int_equal(lk_octree_load_node(octree, i, &node, &error), LK_OK);
        for (size_t p = 0; p < node.vertex_count; p++) sum_out += floor(node.colors[4 * p + 1] * 255.0f + 0.5f);
        lk_mesh_free(&node);
    }
    assert_true(sum_in == sum_out);
    lk_octree_close(octree);
    free(c.xyz);
    /* cut in the middle of the records */
    struct stat info;
    assert_int_equal(stat(path, &info), 0);
    assert_int_equal(truncate(path, info.st_size - 100), 0);
    const char *inputs[1] = {path};
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("milk_cut_pcd"));
    assert_int_equal(lk_octree_build(inputs, 1, dir, &options, NULL, NULL, NULL, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "milk_binary.pcd: byte "));
    assert_non_null(strstr(error.message, "truncated"));
    assert_int_not_equal(access(dir, F_OK), 0);
    lk_mesh_free(&mesh);
}

/* XYZ is streamed line by line in double, like LAS: survey coordinates
 * (UTM eastings of 500 km, millimetres) keep their millimetres, which a
 * float would round to 3 cm; CRLF line ends, comments and blank lines are
 * taken; a bad line is refused with its number before anything is written. */
static void test_xyz_streamed(void **state)
{
    (void)state;
    char path[1024], dir[1024];
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("survey.xyz"));
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("survey"));
    FILE *file = fopen(path, "w");
    assert_non_null(file);
    fprintf(file, "# easting northing height\r\n");
    for (int i = 0; i < 3000; i++) {
        if (i % 1000 == 999) fprintf(file, "\r\n");
        fprintf(file, "%.3f %.3f %.3f\r\n", 500000.0 + 0.017 * i + 3.0 * sin(0.01 * i),
                4100000.0 + 7.0 * cos(0.013 * i), 12.0 + 0.001 * (i % 977));
    }
    fclose(file);
    cloud c;
    read_cloud(path, &c);
    assert_int_equal(c.count, 3000);
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 400;
    options.chunk_points = 1000;
    build(path, dir, &options, NULL);
    check_octree(dir, &c); /* every point within half a step of its double */
    lk_octree *octree;
    lk_error error = {0};
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    double scale = lk_octree_get_info(octree)->scale[0];
    lk_octree_close(octree);
    /* a float reader could not have passed that check */
    assert_true(fabs((double)(float)c.xyz[3] - c.xyz[3]) > 100 * scale);
    free_cloud(&c);
    /* a bad line */
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("bad.xyz"));
    file = fopen(path, "w");
    assert_non_null(file);
    fprintf(file, "1 2 3\n4 5 6\n7 8 x\n");
    fclose(file);
    const char *inputs[1] = {path};
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("bad_xyz"));
    assert_int_equal(lk_octree_build(inputs, 1, dir, &options, NULL, NULL, NULL, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "bad.xyz:3: expected a number, got 'x'"));
    assert_int_not_equal(access(dir, F_OK), 0);
    /* comments only */
    file = fopen(path, "w");
    assert_non_null(file);
    fprintf(file, "# nothing\n\n");
    fclose(file);
    assert_int_equal(lk_octree_build(inputs, 1, dir, &options, NULL, NULL, NULL, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "bad.xyz: no points"));
    assert_int_not_equal(access(dir, F_OK), 0);
}

/* Bad indexes and data files: clear errors, never a crash. */
static void test_bad_index(void **state)
{
    (void)state;
    char dir[1024];
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("bad"));
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 2000;
    build(lk_test_sample("pcd/test_pcd.pcd"), dir, &options, NULL);
    lk_octree *octree;
    lk_error error = {0};
    /* invalid JSON: the line */
    const char *broken = "{\n  \"format\": \"lodkit point octree\",\n  \"version\": 1,\n  oops\n}\n";
    assert_int_equal(lk_octree_open_memory(broken, strlen(broken), "x.json", &octree, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "x.json:4:"));
    assert_null(octree);
    /* a node past the end of the data file */
    char index_path[1100], bin_path[1100];
    snprintf(index_path, sizeof index_path, "%s/octree.json", dir);
    snprintf(bin_path, sizeof bin_path, "%s/octree.bin", dir);
    struct stat info;
    assert_int_equal(stat(bin_path, &info), 0);
    assert_int_equal(truncate(bin_path, info.st_size - 1), 0);
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "past the end"));
    /* a corrupt byte: the CRC */
    assert_int_equal(truncate(bin_path, info.st_size), 0);
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    size_t last = lk_octree_get_info(octree)->node_count - 1;
    FILE *file = fopen(bin_path, "r+b");
    assert_non_null(file);
    fseek(file, (long)lk_octree_node_at(octree, last)->offset, SEEK_SET);
    fputc(0x5a, file);
    fclose(file);
    lk_mesh node;
    assert_int_equal(lk_octree_load_node(octree, last, &node, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "CRC"));
    lk_octree_close(octree);
    /* semantic errors in an otherwise valid index */
    size_t size;
    unsigned char *text = lk_test_read_file(index_path, &size);
    char *edited = malloc(size + 64);
    assert_non_null(edited);
    memcpy(edited, text, size);
    edited[size] = '\0';
    char *level = strstr(edited, "\"level\":\t0");
    assert_non_null(level);
    level[9] = '3';
    assert_int_equal(lk_octree_open_memory(edited, size, "y.json", &octree, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "y.json: nodes[0]"));
    level[9] = '0';
    /* versions: 1 (radii floored by the writer) is read, 3 is not */
    char *version = strstr(edited, "\"version\":\t2");
    assert_non_null(version);
    version[11] = '1';
    assert_int_equal(lk_octree_open_memory(edited, size, "v1.json", &octree, &error), LK_OK);
    lk_octree_close(octree);
    version[11] = '3';
    assert_int_equal(lk_octree_open_memory(edited, size, "v3.json", &octree, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "versions 1 to 2"));
    free(edited);
    /* a clip attribute needs normals (the sample has none) */
    const char *clip = ", {\"name\": \"clip\", \"encoding\": \"snorm8x4\", \"bytes\": 4}";
    edited = malloc(size + strlen(clip) + 1);
    assert_non_null(edited);
    const char *end = strstr((const char *)text, "}],"); /* the attributes' end */
    assert_non_null(end);
    size_t head = (size_t)(end - (const char *)text) + 1;
    memcpy(edited, text, head);
    memcpy(edited + head, clip, strlen(clip));
    memcpy(edited + head + strlen(clip), text + head, size - head);
    assert_int_equal(lk_octree_open_memory(edited, size + strlen(clip), "z.json", &octree, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "clip needs normal"));
    free(edited);
    free(text);
    /* a missing input and an output folder that cannot be made */
    const char *missing[1] = {"/nonexistent/cloud.las"};
    assert_int_not_equal(lk_octree_build(missing, 1, dir, &options, NULL, NULL, NULL, &error), LK_OK);
    assert_non_null(strstr(error.message, "/nonexistent/cloud.las"));
    const char *inputs[1] = {lk_test_sample("pcd/test_pcd.pcd")};
    assert_int_not_equal(lk_octree_build(inputs, 1, "/proc/no/such/dir", &options, NULL, NULL, NULL, &error), LK_OK);
    assert_non_null(strstr(error.message, "/proc/no/such/dir"));
}

/* Share of an octree's points that carry a clip line (per level into
 * level_share when not NULL); checks every clip line on the way: a unit
 * direction across the point's normal, an offset in [0, 1] radii. */
static double clipped_share(const char *dir, double level_share[32])
{
    lk_octree *octree;
    lk_error error = {0};
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    const lk_octree_info *info = lk_octree_get_info(octree);
    assert_true(info->has_clips);
    size_t clipped = 0, total = 0, level_clipped[32] = {0}, level_total[32] = {0};
    for (size_t i = 0; i < info->node_count; i++) {
        lk_mesh node;
        float *clips;
        assert_int_equal(lk_octree_load_node_clips(octree, i, &node, &clips, &error), LK_OK);
        assert_non_null(clips);
        unsigned level = lk_octree_node_at(octree, i)->level;
        for (size_t p = 0; p < node.vertex_count; p++) {
            const float *c = clips + 4 * p, *n = node.normals + 3 * p;
            total++, level_total[level]++;
            if (c[0] == 0 && c[1] == 0 && c[2] == 0) {
                assert_true(c[3] == 0);
                continue;
            }
            clipped++, level_clipped[level]++;
            double length = sqrt((double)c[0] * c[0] + (double)c[1] * c[1] + (double)c[2] * c[2]);
            assert_true(fabs(length - 1) < 0.02); /* snorm8: 1/127 a component */
            assert_true(fabs((double)c[0] * n[0] + (double)c[1] * n[1] + (double)c[2] * n[2]) < 0.03);
            assert_true(c[3] >= 0 && c[3] <= 1);
        }
        lk_mesh_free(&node);
        lk_free(clips);
    }
    if (level_share)
        for (unsigned l = 0; l < 32; l++)
            level_share[l] = level_total[l] ? (double)level_clipped[l] / level_total[l] : -1;
    lk_octree_close(octree);
    return (double)clipped / (double)total;
}

/* Clip lines (the border splats' cuts) are stored with normals, found among
 * each level's points: on a real scan's border (Haystack_Rock, whose
 * returns end at the water and in gaps), not on a closed surface cut into
 * many chunks (the bunny sampled: a chunk's points end at its cube's faces,
 * which are no border; 0.38% of its 100,000 points are cut with 40 chunks,
 * 0.30% with one, 5.4% when the chunk faces were taken for borders; the
 * bunny's own holes underneath are real borders). */
/* The bunny sampled into 100,000 oriented points (lk_mesh_sample_points'
 * defaults), written as a PLY in the test's temporary folder. */
static const char *sampled_bunny(const char *name)
{
    lk_error error = {0};
    lk_mesh bunny, points;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    assert_int_equal(lk_mesh_sample_points(&bunny, NULL, &points, NULL, NULL, &error), LK_OK);
    lk_mesh_free(&bunny);
    const char *ply = lk_test_tmpfile(name);
    assert_int_equal(lk_mesh_write(ply, LK_FORMAT_AUTO, &points, NULL, &error), LK_OK);
    lk_mesh_free(&points);
    return ply;
}

static void test_clip_lines(void **state)
{
    (void)state;
    lk_error error = {0};
    char dir[1024];
    /* a closed surface in many chunks */
    const char *ply = sampled_bunny("bunny100k.ply");
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 2000;
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("bunny_one_chunk"));
    build(ply, dir, &options, NULL);
    double one_chunk = clipped_share(dir, NULL);
    options.chunk_points = 8000;
    lk_octree_stats stats;
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("bunny_chunks"));
    build(ply, dir, &options, &stats);
    assert_true(stats.chunks >= 20);
    double chunks = clipped_share(dir, NULL);
    fprintf(stderr, "bunny sampled: %.2f%% of the points cut in one chunk, %.2f%% in %llu chunks\n", 100 * one_chunk,
            100 * chunks, (unsigned long long)stats.chunks);
    assert_true(one_chunk > 0.001 && one_chunk < 0.006);
    assert_true(chunks > 0.001 && chunks < 0.006);
    /* the same without normals' companions: none stored */
    options.no_clips = 1;
    build(ply, dir, &options, NULL);
    lk_octree *octree;
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    assert_false(lk_octree_get_info(octree)->has_clips);
    assert_int_equal(lk_octree_get_info(octree)->stride, 12 + 4 + 4);
    lk_mesh node;
    float *clips = (float *)&error; /* must become NULL */
    assert_int_equal(lk_octree_load_node_clips(octree, 0, &node, &clips, &error), LK_OK);
    assert_null(clips);
    lk_mesh_free(&node);
    lk_octree_close(octree);

    /* a scan with borders, normals estimated; no normals: no clip lines */
    lk_octree_options_default(&options);
    options.normals = LK_OCTREE_NORMALS_ESTIMATE;
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("haystack_clips"));
    build(lk_test_sample("las/Haystack_Rock.las"), dir, &options, NULL);
    double level_share[32];
    double share = clipped_share(dir, level_share);
    fprintf(stderr, "Haystack_Rock: %.2f%% of the points cut (root %.2f%%)\n", 100 * share, 100 * level_share[0]);
    assert_true(share > 0.02 && share < 0.08); /* measured 3.3% */
    assert_true(level_share[0] > 0.04);        /* the root's sample has its own border: 7.9% */
    options.normals = LK_OCTREE_NORMALS_AUTO;  /* the LAS has none */
    build(lk_test_sample("las/Haystack_Rock.las"), dir, &options, NULL);
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    assert_false(lk_octree_get_info(octree)->has_clips);
    lk_octree_close(octree);
}

/* Potree's adaptive point size (lk_octree_load_selection) against the
 * radii of nodes drawn alone (lk_octree_load_node_clips), on the bunny
 * sampled into 100,000 oriented points, 2,000-point leaves. */
static void test_adaptive_radii(void **state)
{
    (void)state;
    lk_error error = {0};
    const char *ply = sampled_bunny("bunny100k_adaptive.ply");
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 2000;
    char dir[1024];
    snprintf(dir, sizeof dir, "%s", lk_test_tmpfile("bunny_adaptive"));
    build(ply, dir, &options, NULL);
    lk_octree *octree;
    assert_int_equal(lk_octree_open(dir, &octree, &error), LK_OK);
    const lk_octree_info *info = lk_octree_get_info(octree);
    assert_true(info->has_clips);
    size_t node_count = info->node_count;
    size_t *all = malloc(node_count * sizeof *all);
    assert_non_null(all);
    for (size_t i = 0; i < node_count; i++) all[i] = i;
    /* every node drawn: each point at its own radius, never above its node's alone */
    lk_mesh drawn;
    float *clips = NULL;
    assert_int_equal(lk_octree_load_selection(octree, all, node_count, &drawn, &clips, &error), LK_OK);
    assert_int_equal(drawn.vertex_count, (size_t)info->points);
    assert_non_null(clips);
    size_t at = 0, inner = 0, shrunk = 0, cut = 0;
    double inner_sum = 0, alone_sum = 0;
    for (size_t i = 0; i < node_count; i++) {
        const lk_octree_node *header = lk_octree_node_at(octree, i);
        lk_mesh node;
        float *node_clips = NULL;
        assert_int_equal(lk_octree_load_node_clips(octree, i, &node, &node_clips, &error), LK_OK);
        double spacing = ldexp(info->spacing, -(int)header->level);
        for (size_t p = 0; p < node.vertex_count; p++, at++) {
            double alone = node.radii[p], radius = drawn.radii[at];
            assert_true(drawn.positions[3 * at] == node.positions[3 * p]);
            assert_true(radius <= alone * (1 + 1e-6));
            if (header->children) {
                assert_true(alone >= spacing * (1 - 1e-6)); /* drawn alone: at least the spacing */
                inner++;
                inner_sum += radius;
                alone_sum += alone;
                if (radius < 0.999 * alone) shrunk++;
            } else {
                assert_true(radius == alone); /* a leaf's points are its own */
            }
            /* a clip line stays where it was: offset * radius */
            float *c = clips + 4 * at, *a = node_clips + 4 * p;
            assert_true(c[0] == a[0] && c[1] == a[1] && c[2] == a[2]);
            if (a[0] != 0 || a[1] != 0 || a[2] != 0) {
                cut++;
                assert_true(fabs(c[3] * radius - a[3] * alone) <= 1e-5 * alone);
            }
        }
        lk_mesh_free(&node);
        free(node_clips);
    }
    fprintf(stderr,
            "bunny 100k, every node drawn: %zu of %zu inner points shrink, mean radius %.3f of the alone one; %zu "
            "cut\n",
            shrunk, inner, inner_sum / alone_sum, cut);
    assert_true(inner > 10000);
    assert_true(shrunk > inner / 3);           /* measured 47%: the floor set them */
    assert_true(inner_sum < 0.85 * alone_sum); /* measured 0.752 */
    assert_true(cut > 0);
    lk_mesh_free(&drawn);
    free(clips);
    /* a node drawn without its children: the radii it has alone; the root
     * with some of its children: only its points above those shrink */
    lk_mesh root, alone;
    assert_int_equal(lk_octree_load_node(octree, 0, &alone, &error), LK_OK);
    size_t first_children[2] = {0, 0};
    for (int with_child = 0; with_child < 2; with_child++) {
        for (size_t i = 1; i < node_count && with_child && !first_children[1]; i++)
            if (lk_octree_node_at(octree, i)->level == 1) first_children[1] = i;
        assert_int_equal(lk_octree_load_selection(octree, first_children, 1 + (size_t)with_child, &root, NULL, &error),
                         LK_OK);
        size_t smaller = 0;
        for (size_t p = 0; p < alone.vertex_count; p++) {
            assert_true(root.radii[p] <= alone.radii[p]);
            if (root.radii[p] < alone.radii[p]) smaller++;
        }
        fprintf(stderr, "root %s: %zu of its %zu points smaller\n", with_child ? "with one child" : "alone", smaller,
                alone.vertex_count);
        if (with_child)
            assert_true(smaller > 0 && smaller < alone.vertex_count);
        else
            assert_int_equal(smaller, 0);
        lk_mesh_free(&root);
    }
    lk_mesh_free(&alone);
    /* regression: a node of the deepest level (r + 30 digits) in a
     * selection wrote one byte past the child-name buffer */
    char deep[1024];
    snprintf(deep, sizeof deep,
             "{\"format\": \"lodkit point octree\", \"version\": 2, \"data\": \"octree.bin\", \"points\": 0, "
             "\"spacing\": 1, \"scale\": [1e-9, 1e-9, 1e-9], \"offset\": [0, 0, 0], \"cube_size\": 1.073741824, "
             "\"bounds\": {\"min\": [0, 0, 0], \"max\": [1, 1, 1]}, \"stride\": 16, \"attributes\": ["
             "{\"name\": \"position\", \"encoding\": \"int32x3\", \"bytes\": 12}, "
             "{\"name\": \"radius\", \"encoding\": \"float32\", \"bytes\": 4}], \"nodes\": ["
             "{\"name\": \"r\", \"level\": 0, \"points\": 0, \"offset\": 0, \"length\": 0, \"crc32\": 0}, "
             "{\"name\": \"r%s\", \"level\": 30, \"points\": 0, \"offset\": 0, \"length\": 0, \"crc32\": 0}]}",
             "000000000000000000000000000000");
    lk_octree *deep_octree;
    assert_int_equal(lk_octree_open_memory(deep, strlen(deep), "deep.json", &deep_octree, &error), LK_OK);
    size_t deepest = 1;
    assert_int_equal(lk_octree_node_at(deep_octree, deepest)->level, 30);
    assert_int_not_equal(lk_octree_load_selection(deep_octree, &deepest, 1, &root, NULL, &error), LK_OK);
    assert_non_null(strstr(error.message, "without its data file"));
    lk_octree_close(deep_octree);
    /* a node index past the end */
    size_t bad = node_count;
    assert_int_equal(lk_octree_load_selection(octree, &bad, 1, &root, NULL, &error), LK_ERR_INVALID);
    free(all);
    lk_octree_close(octree);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_las_chunks_and_threads),
        cmocka_unit_test(test_kitten_normals),
        cmocka_unit_test(test_small_cloud_levels),
        cmocka_unit_test(test_pcd_colours),
        cmocka_unit_test(test_ply_streamed),
        cmocka_unit_test(test_xyz_streamed),
        cmocka_unit_test(test_pcd_streamed),
        cmocka_unit_test(test_bad_index),
        cmocka_unit_test(test_clip_lines),
        cmocka_unit_test(test_adaptive_radii),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
