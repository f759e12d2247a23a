/* SPDX-License-Identifier: MIT */
/* lodkit convert: a mesh from one format into another, welded, cleaned or
 * moved on the way. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help convert_help = {
    "IN OUT",
    "Convert between mesh formats; the formats come from the file extensions.\n"
    "glTF to glTF keeps the scene: nodes, primitives, materials, textures (notes say\n"
    "what is dropped); so does OBJ to glTF with the .mtl materials and textures.\n"
    "Read: {mesh-read}\n"
    "Write: {mesh-write}\n",
    NULL,
};

int cmd_convert(int argc, char **argv)
{
    lk_write_options write_options = {0};
    int clean = 0, translate = 0, translate_relative = 0;
    double offset[3] = {0, 0, 0};
    cli_parser parser;
    cli_parse_begin(&parser, CMD_CONVERT, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        switch (id) {
        case OPT_ASCII:
            write_options.ply_encoding = LK_PLY_ASCII;
            write_options.stl_ascii = 1;
            break;
        case OPT_BIG_ENDIAN: write_options.ply_encoding = LK_PLY_BINARY_BE; break;
        case OPT_CLEAN: clean = 1; break;
        case OPT_TRANSLATE:
        case OPT_TRANSLATE_DIAGONAL:
            if (!parse_vector3(parser.value, offset))
                return usage_error("convert", "expected X,Y,Z, got '%s'", parser.value);
            translate = 1;
            translate_relative = id == OPT_TRANSLATE_DIAGONAL;
            break;
        case OPT_NO_NORMALS: write_options.skip_normals = 1; break;
        case OPT_NO_TEXCOORDS: write_options.skip_texcoords = 1; break;
        case OPT_NO_COLORS: write_options.skip_colors = 1; break;
        case OPT_QUANTIZE:
        case OPT_MESHOPT:
        case OPT_EXTERNAL_IMAGES: gltf_flag_option(id, &write_options.gltf_flags); break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("convert", "%s", "expected IN and OUT");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = output_mesh_format("convert", out, 1);
    if (out_format == LK_FORMAT_UNKNOWN) return EXIT_USAGE;
    if (check_gltf_flags("convert", out, write_options.gltf_flags)) return EXIT_USAGE;
    if (is_gltf_path(out) && reads_as_scene(in)) {
        /* glTF (or OBJ) to glTF keeps the scene: nodes, primitives, materials. */
        lk_scene scene;
        lk_error error = {0};
        lk_status status = load_scene(in, &scene, &error);
        size_t degenerate = 0, duplicate = 0, unused = 0;
        for (size_t m = 0; status == LK_OK && clean && m < scene.mesh_count; m++)
            for (size_t p = 0; status == LK_OK && p < scene.meshes[m].primitive_count; p++) {
                lk_mesh *primitive = &scene.meshes[m].primitives[p].mesh;
                size_t d = 0, u = 0, n = 0;
                if (primitive->triangle_count == 0) continue;
                status = lk_mesh_remove_degenerate(primitive, &d, &u, &error);
                if (status == LK_OK) status = lk_mesh_remove_unused_vertices(primitive, &n, &error);
                degenerate += d, duplicate += u, unused += n;
            }
        if (status == LK_OK && translate) {
            lk_mesh flat;
            status = lk_scene_flatten(&scene, &flat, &error);
            double scale = status == LK_OK && translate_relative ? lk_mesh_bounds(&flat, NULL, NULL) : 1.0;
            lk_mesh_free(&flat);
            /* a world-space move: every root node moves */
            for (size_t r = 0; status == LK_OK && r < scene.root_count; r++) {
                lk_scene_node *node = &scene.nodes[scene.roots[r]];
                for (int k = 0; k < 3; k++) {
                    node->matrix[12 + k] += offset[k] * scale;
                    node->translation[k] += offset[k] * scale;
                }
            }
        }
        if (status == LK_OK) status = lk_scene_write(out, &scene, &write_options, &error);
        if (status != LK_OK) {
            print_error_for(in, out, &error);
            lk_scene_free(&scene);
            return EXIT_BAD_INPUT;
        }
        if (!quiet) {
            printf("%s: %s -> %s", in, scene_summary(&scene), out);
            if (clean)
                printf(" (removed %s degenerate, %s duplicate triangles, %s unused vertices)", thousands(degenerate),
                       thousands(duplicate), thousands(unused));
            putchar('\n');
            print_scene_notes(&scene);
        }
        lk_scene_free(&scene);
        return EXIT_OK;
    }
    lk_mesh mesh;
    lk_error error = {0};
    size_t merged = 0, degenerate = 0, duplicate = 0, unused = 0;
    lk_status status = load_mesh(in, &mesh, NULL, &merged, &error);
    if (status == LK_OK && clean) status = lk_mesh_remove_degenerate(&mesh, &degenerate, &duplicate, &error);
    if (status == LK_OK && clean) status = lk_mesh_remove_unused_vertices(&mesh, &unused, &error);
    if (status == LK_OK && translate) {
        double scale = translate_relative ? lk_mesh_bounds(&mesh, NULL, NULL) : 1.0;
        lk_mesh_translate(&mesh, offset[0] * scale, offset[1] * scale, offset[2] * scale);
    }
    if (status == LK_OK) status = lk_mesh_write(out, out_format, &mesh, &write_options, &error);
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_mesh_free(&mesh);
        return EXIT_BAD_INPUT;
    }
    if (!quiet) {
        printf("%s: %s, %s -> %s", in, n_vertices(mesh.vertex_count), n_triangles(mesh.triangle_count), out);
        if (cli_weld) printf(" (welded %s)", thousands(merged));
        if (clean)
            printf(" (removed %s degenerate, %s duplicate triangles, %s unused vertices)", thousands(degenerate),
                   thousands(duplicate), thousands(unused));
        putchar('\n');
    }
    lk_mesh_free(&mesh);
    return EXIT_OK;
}
