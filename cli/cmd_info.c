/* SPDX-License-Identifier: MIT */
/* lodkit info: the size, bounds and topology of meshes and point sets, and
 * the size, extent and heights of elevation grids. */
#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help info_help = {
    "FILE...",
    "Print the size, bounds and topology of meshes and point sets\n"
    "({mesh-read})\n"
    "and the size, extent and height range of elevation grids\n"
    "({grid}).\n",
    "With one FILE the report is a list; with several, a table with a row per file.\n"
    "Genus is -1 when the mesh is not a manifold (it is then undefined).\n",
};

static cJSON *stats_json(const char *path, const lk_mesh *mesh, const lk_mesh_stats *stats, double load_seconds)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddStringToObject(object, "file", path);
    cJSON_AddStringToObject(object, "format", lk_format_name(lk_format_from_path(path)));
    cJSON_AddNumberToObject(object, "vertices", (double)stats->vertex_count);
    cJSON_AddNumberToObject(object, "triangles", (double)stats->triangle_count);
    cJSON_AddNumberToObject(object, "used_vertices", (double)stats->used_vertex_count);
    cJSON_AddNumberToObject(object, "edges", (double)stats->edge_count);
    cJSON *attributes = cJSON_AddArrayToObject(object, "attributes"); /* as the text report lists them */
    if (mesh->normals) cJSON_AddItemToArray(attributes, cJSON_CreateString("normals"));
    if (mesh->texcoords) cJSON_AddItemToArray(attributes, cJSON_CreateString("texcoords"));
    if (mesh->colors) cJSON_AddItemToArray(attributes, cJSON_CreateString("colors"));
    if (mesh->radii) cJSON_AddItemToArray(attributes, cJSON_CreateString("radii"));
    cJSON *bbox = cJSON_AddObjectToObject(object, "bbox");
    float min[3], max[3];
    memcpy(min, stats->min, sizeof min);
    memcpy(max, stats->max, sizeof max);
    double minimum[3] = {min[0], min[1], min[2]}, maximum[3] = {max[0], max[1], max[2]};
    cJSON_AddItemToObject(bbox, "min", cJSON_CreateDoubleArray(minimum, 3));
    cJSON_AddItemToObject(bbox, "max", cJSON_CreateDoubleArray(maximum, 3));
    cJSON_AddNumberToObject(object, "diagonal", stats->diagonal);
    cJSON_AddNumberToObject(object, "area", stats->area);
    cJSON_AddNumberToObject(object, "components", (double)stats->component_count);
    cJSON_AddNumberToObject(object, "boundary_edges", (double)stats->boundary_edge_count);
    cJSON_AddNumberToObject(object, "boundary_loops", (double)stats->boundary_loop_count);
    cJSON_AddNumberToObject(object, "nonmanifold_edges", (double)stats->nonmanifold_edge_count);
    cJSON_AddNumberToObject(object, "nonmanifold_vertices", (double)stats->nonmanifold_vertex_count);
    cJSON_AddNumberToObject(object, "degenerate_triangles", (double)stats->degenerate_triangle_count);
    cJSON_AddNumberToObject(object, "duplicate_triangles", (double)stats->duplicate_triangle_count);
    cJSON_AddNumberToObject(object, "euler_characteristic", (double)stats->euler_characteristic);
    cJSON_AddNumberToObject(object, "genus", (double)stats->genus);
    cJSON_AddNumberToObject(object, "load_seconds", load_seconds);
    return object;
}

static void print_stats_list(const char *path, const lk_mesh *mesh, const lk_mesh_stats *stats, double load_seconds)
{
    printf("file                  %s\n", path);
    printf("format                %s\n", lk_format_name(lk_format_from_path(path)));
    printf("vertices              %s\n", thousands(stats->vertex_count));
    printf("triangles             %s\n", thousands(stats->triangle_count));
    if (stats->triangle_count) {
        printf("edges                 %s\n", thousands(stats->edge_count));
        if (stats->used_vertex_count != stats->vertex_count)
            printf("unused vertices       %s\n", thousands(stats->vertex_count - stats->used_vertex_count));
    }
    printf("attributes           %s%s%s%s\n", mesh->normals ? " normals" : "", mesh->texcoords ? " texcoords" : "",
           mesh->colors ? " colors" : "", !mesh->normals && !mesh->texcoords && !mesh->colors ? " none" : "");
    printf("bbox min              %g %g %g\n", (double)stats->min[0], (double)stats->min[1], (double)stats->min[2]);
    printf("bbox max              %g %g %g\n", (double)stats->max[0], (double)stats->max[1], (double)stats->max[2]);
    printf("diagonal              %g\n", stats->diagonal);
    if (stats->triangle_count) {
        printf("area                  %g\n", stats->area);
        printf("components            %s\n", thousands(stats->component_count));
        printf("boundary edges        %s (%s)\n", thousands(stats->boundary_edge_count),
               count_noun(stats->boundary_loop_count, "loop", "loops"));
        printf("non-manifold edges    %s\n", thousands(stats->nonmanifold_edge_count));
        printf("non-manifold vertices %s\n", thousands(stats->nonmanifold_vertex_count));
        printf("degenerate triangles  %s\n", thousands(stats->degenerate_triangle_count));
        printf("duplicate triangles   %s\n", thousands(stats->duplicate_triangle_count));
        printf("euler characteristic  %lld\n", stats->euler_characteristic);
        if (stats->genus >= 0)
            printf("genus                 %lld\n", stats->genus);
        else
            printf("genus                 undefined (not a manifold)\n");
    }
    printf("load time             %.1f ms\n", load_seconds * 1000);
}

static const char *short_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

/* ---- elevation grids ---------------------------------------------------- */

static cJSON *grid_json(const char *path, const lk_heightfield *grid, double load_seconds)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddStringToObject(object, "file", path);
    cJSON_AddStringToObject(object, "format", "grid");
    cJSON_AddNumberToObject(object, "width", (double)grid->width);
    cJSON_AddNumberToObject(object, "height", (double)grid->height);
    cJSON_AddNumberToObject(object, "spacing_x", grid->spacing_x);
    cJSON_AddNumberToObject(object, "spacing_y", grid->spacing_y);
    double minimum[2] = {grid->origin_x, grid->origin_y};
    double maximum[2] = {grid->origin_x + (double)(grid->width - 1) * grid->spacing_x,
                         grid->origin_y + (double)(grid->height - 1) * grid->spacing_y};
    cJSON *extent = cJSON_AddObjectToObject(object, "extent");
    cJSON_AddItemToObject(extent, "min", cJSON_CreateDoubleArray(minimum, 2));
    cJSON_AddItemToObject(extent, "max", cJSON_CreateDoubleArray(maximum, 2));
    cJSON_AddNumberToObject(object, "min_height", grid->min_height);
    cJSON_AddNumberToObject(object, "max_height", grid->max_height);
    cJSON_AddNumberToObject(object, "nodata_filled", (double)grid->nodata_count);
    cJSON_AddNumberToObject(object, "load_seconds", load_seconds);
    return object;
}

static void print_grid_list(const char *path, const lk_heightfield *grid, double load_seconds)
{
    double width = (double)(grid->width - 1) * grid->spacing_x, height = (double)(grid->height - 1) * grid->spacing_y;
    printf("file                  %s\n", path);
    printf("format                elevation grid (lodkit terrain flies over it)\n");
    printf("samples               %s x %s (%s)\n", thousands(grid->width), thousands(grid->height),
           thousands((unsigned long long)grid->width * grid->height));
    printf("spacing               %g x %g m\n", grid->spacing_x, grid->spacing_y);
    printf("extent                x %g .. %g, y %g .. %g m (%g x %g km)\n", grid->origin_x, grid->origin_x + width,
           grid->origin_y, grid->origin_y + height, width / 1000, height / 1000);
    printf("heights               %g .. %g m\n", grid->min_height, grid->max_height);
    if (grid->nodata_count) printf("no-data filled        %s\n", count_noun(grid->nodata_count, "sample", "samples"));
    printf("load time             %.1f ms\n", load_seconds * 1000);
}

/* Reads PATH as an elevation grid (within the memory budget) and reports it. */
static int info_grid(const char *path, int json, int quiet, int file_count)
{
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.max_samples = cli_max_memory / LK_DEM_BYTES_PER_SAMPLE;
    if (options.max_samples < 4) options.max_samples = 4;
    progress_state progress;
    progress_init(&progress, quiet || json, "info");
    options.progress = progress_draw;
    options.progress_user = &progress;
    lk_heightfield grid;
    lk_error error = {0};
    double start = now_seconds();
    lk_status status = lk_dem_read(path, &options, &grid, &error);
    double seconds = now_seconds() - start;
    progress_done(&progress);
    if (status != LK_OK) {
        print_error_for(path, NULL, &error);
        return EXIT_BAD_INPUT;
    }
    if (json) {
        print_json(grid_json(path, &grid, seconds));
    } else if (file_count == 1) {
        print_grid_list(path, &grid, seconds);
    } else {
        printf("%-24s elevation grid %zu x %zu, heights %g .. %g m (loaded in %.1f ms)\n", short_name(path), grid.width,
               grid.height, grid.min_height, grid.max_height, seconds * 1000);
    }
    lk_heightfield_free(&grid);
    return EXIT_OK;
}

/* What a glTF scene holds, for `info --json` (and round-trip tests): the
 * node tree, each mesh's primitives with their counts, attributes and
 * material, the materials' JSON, textures and images (size and FNV-1a
 * hash of their bytes), skins and animations (their indices, and hashes
 * of their joints, weights, matrices and keys). */
/* Primitives drawn by the node tree (a mesh used twice counts twice):
 * what a glTF loader creates as meshes. The reader checked that the
 * nodes form trees. */
static size_t drawn_primitives(const lk_scene *scene, uint32_t node, size_t depth)
{
    if (node >= scene->node_count || depth > scene->node_count) return 0;
    const lk_scene_node *n = &scene->nodes[node];
    size_t count = n->mesh >= 0 ? scene->meshes[n->mesh].primitive_count : 0;
    for (size_t c = 0; c < n->child_count; c++) count += drawn_primitives(scene, n->children[c], depth + 1);
    return count;
}

/* FNV-1a of `size` bytes (NULL: of nothing) as 8 hex digits. */
static cJSON *hash_json(const void *data, size_t size)
{
    const unsigned char *bytes = data;
    uint32_t hash = 2166136261u;
    for (size_t b = 0; bytes && b < size; b++) hash = (hash ^ bytes[b]) * 16777619u;
    char hex[9];
    snprintf(hex, sizeof hex, "%08x", hash);
    return cJSON_CreateString(hex);
}

static void add_skins_and_animations(cJSON *object, const lk_scene *scene)
{
    static const char *const paths[] = {"translation", "rotation", "scale", "weights"};
    static const char *const interpolations[] = {"LINEAR", "STEP", "CUBICSPLINE"};
    cJSON *skins = cJSON_AddArrayToObject(object, "skins");
    for (size_t i = 0; i < scene->skin_count; i++) {
        const lk_scene_skin *skin = &scene->skins[i];
        cJSON *json = cJSON_CreateObject();
        cJSON_AddItemToArray(skins, json);
        if (skin->name) cJSON_AddStringToObject(json, "name", skin->name);
        cJSON *joints = cJSON_AddArrayToObject(json, "joints");
        for (size_t j = 0; j < skin->joint_count; j++)
            cJSON_AddItemToArray(joints, cJSON_CreateNumber(skin->joints[j]));
        if (skin->skeleton >= 0) cJSON_AddNumberToObject(json, "skeleton", skin->skeleton);
        cJSON_AddItemToObject(json, "inverse_bind_matrices",
                              hash_json(skin->inverse_bind_matrices,
                                        skin->inverse_bind_matrices ? 16 * skin->joint_count * sizeof(float) : 0));
    }
    cJSON *animations = cJSON_AddArrayToObject(object, "animations");
    for (size_t a = 0; a < scene->animation_count; a++) {
        const lk_scene_animation *animation = &scene->animations[a];
        cJSON *json = cJSON_CreateObject();
        cJSON_AddItemToArray(animations, json);
        if (animation->name) cJSON_AddStringToObject(json, "name", animation->name);
        cJSON *channels = cJSON_AddArrayToObject(json, "channels");
        for (size_t c = 0; c < animation->channel_count; c++) {
            const lk_scene_animation_channel *channel = &animation->channels[c];
            cJSON *item = cJSON_CreateObject();
            cJSON_AddItemToArray(channels, item);
            cJSON_AddNumberToObject(item, "sampler", channel->sampler);
            cJSON_AddNumberToObject(item, "node", channel->node);
            cJSON_AddStringToObject(item, "path", paths[(unsigned)channel->path < 4 ? channel->path : 0]);
        }
        cJSON *samplers = cJSON_AddArrayToObject(json, "samplers");
        for (size_t s = 0; s < animation->sampler_count; s++) {
            const lk_scene_animation_sampler *sampler = &animation->samplers[s];
            cJSON *item = cJSON_CreateObject();
            cJSON_AddItemToArray(samplers, item);
            cJSON_AddStringToObject(item, "interpolation",
                                    interpolations[(unsigned)sampler->interpolation < 3 ? sampler->interpolation : 0]);
            cJSON_AddNumberToObject(item, "keys", (double)sampler->key_count);
            cJSON_AddNumberToObject(item, "components", sampler->components);
            cJSON_AddItemToObject(item, "input", hash_json(sampler->input, sampler->key_count * sizeof(float)));
            cJSON_AddItemToObject(
                item, "output",
                hash_json(sampler->output, sampler->output_count * sampler->components * sizeof(float)));
        }
    }
}

static cJSON *scene_json(const lk_scene *scene)
{
    cJSON *object = cJSON_CreateObject();
    size_t drawn = 0;
    for (size_t r = 0; r < scene->root_count; r++) drawn += drawn_primitives(scene, scene->roots[r], 0);
    cJSON_AddNumberToObject(object, "drawn_primitives", (double)drawn);
    cJSON *roots = cJSON_AddArrayToObject(object, "roots");
    for (size_t r = 0; r < scene->root_count; r++) cJSON_AddItemToArray(roots, cJSON_CreateNumber(scene->roots[r]));
    cJSON *nodes = cJSON_AddArrayToObject(object, "nodes");
    for (size_t i = 0; i < scene->node_count; i++) {
        const lk_scene_node *node = &scene->nodes[i];
        cJSON *json = cJSON_CreateObject();
        cJSON_AddItemToArray(nodes, json);
        if (node->name) cJSON_AddStringToObject(json, "name", node->name);
        if (node->mesh >= 0) cJSON_AddNumberToObject(json, "mesh", node->mesh);
        if (node->camera >= 0) cJSON_AddNumberToObject(json, "camera", node->camera);
        if (node->skin >= 0 && (size_t)node->skin < scene->skin_count)
            cJSON_AddNumberToObject(json, "skin", node->skin);
        cJSON *children = cJSON_AddArrayToObject(json, "children");
        for (size_t c = 0; c < node->child_count; c++)
            cJSON_AddItemToArray(children, cJSON_CreateNumber(node->children[c]));
        /* at float precision: a double's last digit may not survive a
         * JSON round trip (cJSON prints 15 digits when they come within an
         * epsilon) */
        double matrix[16];
        for (int k = 0; k < 16; k++) matrix[k] = (double)(float)node->matrix[k];
        cJSON_AddItemToObject(json, "matrix", cJSON_CreateDoubleArray(matrix, 16));
        if (node->weights && node->mesh >= 0)
            cJSON_AddItemToObject(json, "weights",
                                  hash_json(node->weights, scene->meshes[node->mesh].target_count * sizeof(float)));
    }
    cJSON *meshes = cJSON_AddArrayToObject(object, "meshes");
    for (size_t m = 0; m < scene->mesh_count; m++) {
        const lk_scene_mesh *mesh = &scene->meshes[m];
        cJSON *json = cJSON_CreateObject(), *primitives;
        cJSON_AddItemToArray(meshes, json);
        if (mesh->name) cJSON_AddStringToObject(json, "name", mesh->name);
        primitives = cJSON_AddArrayToObject(json, "primitives");
        for (size_t p = 0; p < mesh->primitive_count; p++) {
            const lk_scene_primitive *primitive = &mesh->primitives[p];
            cJSON *item = cJSON_CreateObject();
            cJSON_AddItemToArray(primitives, item);
            cJSON_AddNumberToObject(item, "vertices", (double)primitive->mesh.vertex_count);
            cJSON_AddNumberToObject(item, "triangles", (double)primitive->mesh.triangle_count);
            if (primitive->line_count) {
                cJSON_AddNumberToObject(item, "lines", (double)primitive->line_count);
                cJSON_AddItemToObject(item, "line_indices",
                                      hash_json(primitive->lines, 2 * primitive->line_count * sizeof(uint32_t)));
            }
            cJSON *attributes = cJSON_AddArrayToObject(item, "attributes");
            if (primitive->mesh.normals) cJSON_AddItemToArray(attributes, cJSON_CreateString("normals"));
            if (primitive->tangents) cJSON_AddItemToArray(attributes, cJSON_CreateString("tangents"));
            if (primitive->mesh.texcoords) cJSON_AddItemToArray(attributes, cJSON_CreateString("texcoords"));
            if (primitive->texcoords1) cJSON_AddItemToArray(attributes, cJSON_CreateString("texcoords1"));
            if (primitive->mesh.colors) cJSON_AddItemToArray(attributes, cJSON_CreateString("colors"));
            if (primitive->joints) {
                size_t count = 4 * primitive->mesh.vertex_count;
                cJSON_AddItemToArray(attributes, cJSON_CreateString("joints"));
                cJSON_AddItemToObject(item, "joints", hash_json(primitive->joints, count * sizeof(uint16_t)));
            }
            if (primitive->weights) {
                size_t count = 4 * primitive->mesh.vertex_count;
                cJSON_AddItemToArray(attributes, cJSON_CreateString("weights"));
                cJSON_AddItemToObject(item, "weights", hash_json(primitive->weights, count * sizeof(float)));
            }
            if (primitive->material >= 0) cJSON_AddNumberToObject(item, "material", primitive->material);
            if (mesh->target_count) {
                /* morph targets: their number and each kind of delta's hash */
                size_t deltas = 3 * mesh->target_count * primitive->mesh.vertex_count * sizeof(float);
                cJSON *targets = cJSON_AddObjectToObject(item, "targets");
                cJSON_AddNumberToObject(targets, "count", (double)mesh->target_count);
                if (primitive->target_positions)
                    cJSON_AddItemToObject(targets, "positions", hash_json(primitive->target_positions, deltas));
                if (primitive->target_normals)
                    cJSON_AddItemToObject(targets, "normals", hash_json(primitive->target_normals, deltas));
                if (primitive->target_tangents)
                    cJSON_AddItemToObject(targets, "tangents", hash_json(primitive->target_tangents, deltas));
            }
        }
        if (mesh->target_count) {
            if (mesh->weights)
                cJSON_AddItemToObject(json, "weights", hash_json(mesh->weights, mesh->target_count * sizeof(float)));
            cJSON *names = mesh->target_names ? cJSON_AddArrayToObject(json, "target_names") : NULL;
            for (size_t k = 0; names && k < mesh->target_count; k++)
                cJSON_AddItemToArray(names, cJSON_CreateString(mesh->target_names[k] ? mesh->target_names[k] : ""));
        }
    }
    cJSON *materials = cJSON_AddArrayToObject(object, "materials");
    for (size_t i = 0; i < scene->material_count; i++)
        cJSON_AddItemToArray(materials, cJSON_CreateString(scene->materials[i].json ? scene->materials[i].json : "{}"));
    cJSON *textures = cJSON_AddArrayToObject(object, "textures");
    for (size_t i = 0; i < scene->texture_count; i++)
        cJSON_AddItemToArray(textures, cJSON_CreateString(scene->textures[i].json ? scene->textures[i].json : "{}"));
    cJSON *samplers = cJSON_AddArrayToObject(object, "samplers");
    for (size_t i = 0; i < scene->sampler_count; i++)
        cJSON_AddItemToArray(samplers, cJSON_CreateString(scene->samplers[i]));
    cJSON *cameras = cJSON_AddArrayToObject(object, "cameras");
    for (size_t i = 0; i < scene->camera_count; i++)
        cJSON_AddItemToArray(cameras, cJSON_CreateString(scene->cameras[i]));
    add_skins_and_animations(object, scene);
    cJSON *images = cJSON_AddArrayToObject(object, "images");
    for (size_t i = 0; i < scene->image_count; i++) {
        const lk_scene_image *image = &scene->images[i];
        uint32_t hash = 2166136261u;
        for (size_t b = 0; b < image->size; b++) hash = (hash ^ image->data[b]) * 16777619u;
        char hex[9];
        snprintf(hex, sizeof hex, "%08x", hash);
        cJSON *json = cJSON_CreateObject();
        cJSON_AddItemToArray(images, json);
        cJSON_AddStringToObject(json, "mime_type", image->mime_type ? image->mime_type : "");
        cJSON_AddNumberToObject(json, "bytes", (double)image->size);
        cJSON_AddStringToObject(json, "fnv1a", hex);
    }
    return object;
}

/* The glTF file reads as a scene whose primitives are lines only (no
 * triangles, no points): what lk_mesh_read refuses with LK_ERR_UNSUPPORTED. */
static bool lines_only_scene(const char *path)
{
    lk_scene scene;
    lk_scene_init(&scene);
    lk_error error = {0};
    bool lines = false, other = false;
    if (load_scene(path, &scene, &error) == LK_OK)
        for (size_t m = 0; m < scene.mesh_count; m++)
            for (size_t p = 0; p < scene.meshes[m].primitive_count; p++) {
                const lk_scene_primitive *primitive = &scene.meshes[m].primitives[p];
                lines = lines || primitive->line_count > 0;
                other = other || (primitive->mesh.vertex_count > 0 && primitive->line_count == 0);
            }
    lk_scene_free(&scene);
    return lines && !other;
}

int cmd_info(int argc, char **argv)
{
    cli_parser parser;
    cli_parse_begin(&parser, CMD_INFO, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) return cli_unhandled(&parser, id);
    int json = parser.json;
    if (optind >= argc) return usage_error("info", "%s", "missing FILE");
    int file_count = argc - optind, result = EXIT_OK;
    if (file_count > 1 && !json)
        printf("%-24s %10s %10s %10s %5s %8s %8s %5s %9s\n", "file", "vertices", "triangles", "diagonal", "comp",
               "boundary", "nonmanif", "genus", "load ms");
    for (int i = optind; i < argc; i++) {
        lk_mesh mesh;
        lk_error error = {0};
        double seconds;
        lk_mesh_stats stats;
        lk_status status = load_mesh(argv[i], &mesh, &seconds, NULL, &error);
        /* A glTF of lines only is no mesh, but a scene: described as one
         * with an empty mesh. */
        if (status == LK_ERR_UNSUPPORTED && is_gltf_path(argv[i]) && lines_only_scene(argv[i])) {
            lk_mesh_init(&mesh);
            status = LK_OK;
        }
        /* A file no mesh reader knows may be an elevation grid: describe it. */
        if (status == LK_ERR_UNSUPPORTED && lk_format_from_path(argv[i]) == LK_FORMAT_UNKNOWN &&
            looks_like_grid(argv[i])) {
            if (info_grid(argv[i], json, parser.quiet, file_count) != EXIT_OK) result = EXIT_BAD_INPUT;
            continue;
        }
        if (status != LK_OK || lk_mesh_compute_stats(&mesh, &stats, &error) != LK_OK) {
            print_error_for(argv[i], NULL, &error);
            lk_mesh_free(&mesh);
            result = EXIT_BAD_INPUT;
            continue;
        }
        lk_scene scene;
        lk_scene_init(&scene);
        if (reads_as_scene(argv[i]) && load_scene(argv[i], &scene, &error) != LK_OK) {
            print_error_for(argv[i], NULL, &error);
            lk_mesh_free(&mesh);
            result = EXIT_BAD_INPUT;
            continue;
        }
        if (json) {
            cJSON *object = stats_json(argv[i], &mesh, &stats, seconds);
            if (scene.node_count) cJSON_AddItemToObject(object, "scene", scene_json(&scene));
            print_json(object);
        } else if (file_count == 1 && scene.node_count) {
            print_stats_list(argv[i], &mesh, &stats, seconds);
            printf("scene                %s\n", scene_summary(&scene));
            print_scene_notes(&scene);
        } else if (file_count == 1) {
            print_stats_list(argv[i], &mesh, &stats, seconds);
        } else {
            char genus[24];
            if (stats.genus >= 0)
                snprintf(genus, sizeof genus, "%lld", stats.genus);
            else
                snprintf(genus, sizeof genus, "-");
            printf("%-24s %10s %10s %10.4g %5s %8s %8s %5s %9.1f\n", short_name(argv[i]), thousands(stats.vertex_count),
                   thousands(stats.triangle_count), stats.diagonal, thousands(stats.component_count),
                   thousands(stats.boundary_edge_count), thousands(stats.nonmanifold_edge_count), genus,
                   seconds * 1000);
        }
        lk_scene_free(&scene);
        lk_mesh_free(&mesh);
    }
    return result;
}
