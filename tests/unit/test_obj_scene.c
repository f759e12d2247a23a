/* SPDX-License-Identifier: MIT */
/* The OBJ scene reader (src/io_obj_scene.c, lk_scene_read of a .obj):
 * Assimp's OBJ samples with their .mtl files (spider with five JPEG
 * textures, materials with spaces in their names, a usemtl no .mtl defines,
 * an mtllib after `g` naming a missing file, an empty material name), and
 * small .obj/.mtl sets written here for each mapping, note and error. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testutil.h"

#define OBJ_DIR "assimp/OBJ/"

static lk_status read_scene(const char *path, lk_scene *scene, lk_error *error)
{
    lk_error_clear(error);
    return lk_scene_read(path, NULL, scene, error);
}

static size_t primitive_count(const lk_scene *scene)
{
    size_t count = 0;
    for (size_t m = 0; m < scene->mesh_count; m++) count += scene->meshes[m].primitive_count;
    return count;
}

static const lk_scene_material *material_named(const lk_scene *scene, const char *name)
{
    for (size_t i = 0; i < scene->material_count; i++)
        if (scene->materials[i].name && strcmp(scene->materials[i].name, name) == 0) return &scene->materials[i];
    return NULL;
}

static bool has_note(const lk_scene *scene, const char *text)
{
    return scene->notes && strstr(scene->notes, text) != NULL;
}

/* The triangles lk_mesh_read finds in the same file. */
static size_t mesh_reader_triangles(const char *path)
{
    lk_mesh mesh;
    lk_test_load(path, &mesh);
    size_t triangles = mesh.triangle_count;
    lk_mesh_free(&mesh);
    return triangles;
}

/* Distinct usemtl names of a file (each on its own line, trimmed). */
static size_t used_material_count(const char *path)
{
    size_t size;
    char *text = (char *)lk_test_read_file(path, &size);
    text[size] = '\0';
    char names[64][128];
    size_t count = 0;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        if (strncmp(line, "usemtl", 6) != 0) continue;
        char *name = line + 6;
        while (*name == ' ') name++;
        size_t length = strcspn(name, "\r");
        while (length && name[length - 1] == ' ') length--;
        name[length] = '\0';
        bool seen = false;
        for (size_t i = 0; i < count && !seen; i++) seen = strcmp(names[i], name) == 0;
        if (!seen && count < 64) snprintf(names[count++], sizeof names[0], "%s", name);
    }
    free(text);
    return count;
}

static void assert_color(const float *color, double r, double g, double b, double a)
{
    assert_true(fabs(color[0] - r) < 1e-6 && fabs(color[1] - g) < 1e-6 && fabs(color[2] - b) < 1e-6 &&
                fabs(color[3] - a) < 1e-6);
}

/* spider.obj: 4 of the 5 materials of spider.mtl are used, each with its
 * map_Kd (".\\wal67ar_small.jpg": a Windows separator) read from the folder. */
static void test_spider(void **state)
{
    (void)state;
    const char *path = lk_test_sample(OBJ_DIR "spider.obj");
    lk_scene scene;
    lk_error error;
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(scene.node_count, 1);
    assert_int_equal(scene.mesh_count, 1);
    assert_int_equal(primitive_count(&scene), used_material_count(path));
    assert_int_equal(primitive_count(&scene), 4);
    assert_int_equal(lk_scene_triangle_count(&scene), mesh_reader_triangles(path));
    assert_int_equal(scene.material_count, 4);
    assert_int_equal(scene.texture_count, 4);
    assert_int_equal(scene.image_count, 4);
    assert_null(scene.notes);
    /* First-use order of usemtl: HLeibTex, Skin, BeinTex, Augentex. */
    const char *order[] = {"HLeibTex", "Skin", "BeinTex", "Augentex"};
    for (size_t p = 0; p < 4; p++) {
        int32_t material = scene.meshes[0].primitives[p].material;
        assert_true(material >= 0);
        assert_string_equal(scene.materials[material].name, order[p]);
    }
    const lk_scene_material *skin = material_named(&scene, "Skin");
    assert_non_null(skin);
    assert_color(skin->base_color, 0.827451, 0.792157, 0.772549, 1.0);
    assert_true(skin->base_color_texture >= 0);
    const lk_scene_image *image = &scene.images[scene.textures[skin->base_color_texture].image];
    assert_string_equal(image->name, "wal67ar_small.jpg");
    assert_string_equal(image->mime_type, "image/jpeg");
    size_t size;
    unsigned char *bytes = lk_test_read_file(lk_test_sample(OBJ_DIR "wal67ar_small.jpg"), &size);
    assert_int_equal(image->size, size);
    assert_memory_equal(image->data, bytes, size);
    free(bytes);
    assert_non_null(strstr(skin->json, "\"baseColorTexture\":{\"index\":"));
    assert_non_null(strstr(skin->json, "\"metallicFactor\":0"));
    assert_non_null(strstr(skin->json, "\"roughnessFactor\":1")); /* Ks 0: no highlight */
    const lk_scene_material *body = material_named(&scene, "HLeibTex");
    assert_color(body->base_color, 0.690196, 0.639216, 0.615686, 1.0);
    assert_string_equal(scene.images[scene.textures[body->base_color_texture].image].name, "SpiderTex.jpg");

    /* Texture coordinates keep OBJ's v (lodkit's convention, v up): the
     * drawn scene has the mesh reader's range of them. */
    lk_mesh flat, mesh;
    assert_int_equal(lk_scene_flatten(&scene, &flat, &error), LK_OK);
    lk_test_load(path, &mesh);
    assert_non_null(flat.texcoords);
    float range[2][4] = {{1e30f, 1e30f, -1e30f, -1e30f}, {1e30f, 1e30f, -1e30f, -1e30f}};
    const lk_mesh *meshes[2] = {&flat, &mesh};
    for (int k = 0; k < 2; k++)
        for (size_t v = 0; v < meshes[k]->vertex_count; v++)
            for (int c = 0; c < 2; c++) {
                float value = meshes[k]->texcoords[2 * v + (size_t)c];
                if (value < range[k][c]) range[k][c] = value;
                if (value > range[k][2 + c]) range[k][2 + c] = value;
            }
    for (int c = 0; c < 4; c++) assert_true(fabsf(range[0][c] - range[1][c]) < 1e-6f);
    lk_mesh_free(&flat);
    lk_mesh_free(&mesh);
    lk_scene_free(&scene);
}

/* Assimp's material tests: names with spaces, a material no .mtl defines,
 * an mtllib (after `g`) naming a file that is not there, an empty name. */
static void test_assimp_material_files(void **state)
{
    (void)state;
    lk_scene scene;
    lk_error error;

    const char *path = lk_test_sample(OBJ_DIR "cube_usemtl.obj");
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), used_material_count(path));
    assert_int_equal(primitive_count(&scene), 3);
    assert_int_equal(lk_scene_triangle_count(&scene), mesh_reader_triangles(path));
    assert_string_equal(scene.materials[0].name, "mtl3");
    assert_string_equal(scene.materials[1].name, "mtl");
    assert_string_equal(scene.materials[2].name, "mtl2");
    assert_true(has_note(&scene, "material \"mtl3\" is used but no .mtl read defines it"));
    assert_color(scene.materials[0].base_color, 1, 1, 1, 1);
    /* mtl2: Ns 16, Ks 0.375: roughness 1 - sqrt(16 / 1000) = 0.8735 */
    assert_non_null(strstr(scene.materials[2].json, "\"roughnessFactor\":0.8735"));
    assert_int_equal(scene.texture_count, 0);
    lk_scene_free(&scene);

    path = lk_test_sample(OBJ_DIR "space_in_material_name.obj");
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), 1);
    assert_int_equal(lk_scene_triangle_count(&scene), mesh_reader_triangles(path));
    const lk_scene_material *plastic = material_named(&scene, "Hard Shiny Plastic White");
    assert_non_null(plastic);
    assert_color(plastic->base_color, 0.141176, 0.184314, 0.411765, 1.0);
    assert_null(scene.notes);
    lk_scene_free(&scene);

    path = lk_test_sample(OBJ_DIR "cube_mtllib_after_g.obj");
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), 1);
    assert_true(has_note(&scene, "mtllib cube_mtllib_after_g.mat not read"));
    assert_non_null(material_named(&scene, "MyMaterial"));
    lk_scene_free(&scene);

    path = lk_test_sample(OBJ_DIR "empty_mat.obj");
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), 1);
    assert_int_equal(lk_scene_triangle_count(&scene), mesh_reader_triangles(path));
    assert_int_equal(scene.material_count, 1);
    assert_color(scene.materials[0].base_color, 0.8, 0.8, 0.8, 1.0); /* "newmtl " with Kd 0.8 */
    lk_scene_free(&scene);

    /* regr01.mtl names a material in Latin-1: glTF's JSON gets UTF-8. */
    path = lk_test_sample(OBJ_DIR "regr01.obj");
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), used_material_count(path));
    assert_non_null(material_named(&scene, "Terraind\xC3\xA6k"));
    assert_true(has_note(&scene, "read as Latin-1"));
    lk_scene_free(&scene);
}

/* Writes the files of a model into a fresh folder below the test's tmpdir. */
static const char *make_folder(const char *name)
{
    static char folder[512];
    snprintf(folder, sizeof folder, "%s", lk_test_tmpfile(name));
    mkdir(folder, 0755);
    return folder;
}

static void write_text(const char *folder, const char *name, const char *text)
{
    lk_test_write_file(lk_test_path(folder, name), text, strlen(text));
}

static const unsigned char png_bytes[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R'};

/* Every mapping of the .mtl, texture options and paths, notes. */
static void test_built_materials(void **state)
{
    (void)state;
    const char *folder = make_folder("built");
    char sub[600];
    snprintf(sub, sizeof sub, "%s/sub", folder);
    mkdir(sub, 0755);
    lk_test_write_file(lk_test_path(folder, "sub/color.png"), png_bytes, sizeof png_bytes);
    lk_test_write_file(lk_test_path(folder, "bumps.png"), png_bytes, sizeof png_bytes);
    lk_test_write_file(lk_test_path(folder, "not_an_image.tga"), "TGA?", 4);
    write_text(folder, "a.mtl",
               "# first file\n"
               "newmtl glass\n"
               "Kd 0.2 0.4 0.6\n"
               "d 0.5\n"
               "Ns 250\n"
               "Ks 1 1 1\n"
               "map_Kd -s 2 2 1 -o 0.5 0.5 -bm 1 .\\sub\\color.png\n"
               "map_d alpha.png\n"
               "newmtl lamp\n"
               "Kd 1\n"
               "Tr 0.25\n"
               "Ke 1 0.5 0\n"
               "map_Bump -bm 0.5 bumps.png\n"
               "map_Ks spec.png\n");
    write_text(folder, "b c.mtl",
               "newmtl missing\n"
               "map_Kd nowhere.png\n"
               "newmtl outside\n"
               "map_Kd ../x.png\n"
               "newmtl other\n"
               "map_Kd not_an_image.tga\n"
               "newmtl glass\n"
               "Kd 0 0 0\n");
    write_text(folder, "m.obj",
               "mtllib a.mtl\n"
               "o Thing\n"
               "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
               "vt 0.25 0.75\nvt 1 0\nvt 1 1\nvt 0 1\n"
               "vn 0 0 1\n"
               "f 1 2 3\n" /* before any usemtl: no material */
               "usemtl glass\n"
               "f -4/-4/-1 -3/-3/-1 -2/-2/-1 -1/-1/-1\n" /* a quad: 2 triangles, 4 vertices */
               "usemtl lamp\n"
               "f 1/1 2/2 3/3\n"
               "usemtl glass\n"
               "f 1/2/1 2/2/1 3/3/1\n" /* v 1 with vt 2: one more vertex */
               "mtllib b c.mtl\n"      /* after use, a name with a space */
               "usemtl missing\nf 1 2 3\n"
               "usemtl outside\nf 1 2 3\n"
               "usemtl other\nf 1 2 3\n");
    const char *path = lk_test_path(folder, "m.obj");
    lk_scene scene;
    lk_error error;
    assert_int_equal(read_scene(path, &scene, &error), LK_OK);
    assert_int_equal(lk_scene_triangle_count(&scene), mesh_reader_triangles(path));
    assert_int_equal(primitive_count(&scene), 6);
    assert_string_equal(scene.nodes[0].name, "Thing");
    const lk_scene_primitive *primitives = scene.meshes[0].primitives;
    assert_int_equal(primitives[0].material, -1);
    assert_int_equal(primitives[0].mesh.triangle_count, 1);
    assert_null(primitives[0].mesh.texcoords);
    /* glass: the quad (4 vertices) and a triangle whose v 1 and v 2 come with vt 2 */
    assert_int_equal(primitives[1].mesh.triangle_count, 3);
    assert_int_equal(primitives[1].mesh.vertex_count, 5);
    assert_non_null(primitives[1].mesh.normals);
    assert_true(primitives[1].mesh.texcoords[0] == 0.25f && primitives[1].mesh.texcoords[1] == 0.75f);
    assert_int_equal(scene.material_count, 5);

    const lk_scene_material *glass = material_named(&scene, "glass");
    assert_color(glass->base_color, 0.2, 0.4, 0.6, 0.5); /* the first definition wins */
    assert_non_null(strstr(glass->json, "\"alphaMode\":\"BLEND\""));
    assert_non_null(strstr(glass->json, "\"roughnessFactor\":0.5")); /* 1 - sqrt(250 / 1000) */
    assert_true(glass->base_color_texture >= 0);
    const lk_scene_image *color = &scene.images[scene.textures[glass->base_color_texture].image];
    assert_string_equal(color->mime_type, "image/png");
    assert_string_equal(color->name, "color.png");
    assert_int_equal(color->size, sizeof png_bytes);

    const lk_scene_material *lamp = material_named(&scene, "lamp");
    assert_color(lamp->base_color, 1, 1, 1, 0.75);
    assert_non_null(strstr(lamp->json, "\"emissiveFactor\":[1,0.5,0]"));
    assert_non_null(strstr(lamp->json, "\"normalTexture\":{\"index\":"));
    assert_int_equal(lamp->base_color_texture, -1);
    assert_int_equal(scene.texture_count, 2);
    assert_int_equal(scene.image_count, 2);

    for (const char *name = "missing\0outside\0other\0"; *name; name += strlen(name) + 1) {
        const lk_scene_material *material = material_named(&scene, name);
        assert_non_null(material);
        assert_int_equal(material->base_color_texture, -1);
        assert_null(strstr(material->json, "baseColorTexture"));
    }
    assert_true(has_note(&scene, "map_d (an alpha texture) ignored"));
    assert_true(has_note(&scene, "map_Ks ignored"));
    assert_true(has_note(&scene, "option -s"));
    assert_true(has_note(&scene, "material \"glass\" defined again"));
    assert_true(has_note(&scene, "texture nowhere.png not read"));
    assert_true(has_note(&scene, "texture ../x.png not read"));
    assert_true(has_note(&scene, "texture not_an_image.tga dropped (not a PNG or JPEG"));

    /* The whole scene writes as glTF and reads back with its materials. */
    const char *glb = lk_test_tmpfile("built.glb");
    assert_int_equal(lk_scene_write(glb, &scene, NULL, &error), LK_OK);
    lk_scene back;
    assert_int_equal(read_scene(glb, &back, &error), LK_OK);
    assert_int_equal(back.material_count, 5);
    assert_int_equal(back.texture_count, 2);
    assert_int_equal(primitive_count(&back), 6);
    const lk_scene_material *glass_back = material_named(&back, "glass");
    assert_color(glass_back->base_color, 0.2, 0.4, 0.6, 0.5);
    /* v is flipped to glTF's convention on the way out and back on the way in */
    const lk_mesh *quad = &back.meshes[0].primitives[1].mesh;
    bool found = false;
    for (size_t v = 0; v < quad->vertex_count; v++)
        found |= fabsf(quad->texcoords[2 * v] - 0.25f) < 1e-3f && fabsf(quad->texcoords[2 * v + 1] - 0.75f) < 1e-3f;
    assert_true(found);
    lk_scene_free(&back);
    lk_scene_free(&scene);
}

/* One .mtl named twice (a second name for the same file, a hard link) is
 * read once: a file of N mtllib lines naming one large .mtl must not parse
 * it N times. */
static void test_same_mtl_once(void **state)
{
    (void)state;
    const char *folder = make_folder("same");
    write_text(folder, "a.mtl", "newmtl x\nKd 1 0 0\n");
    char first[600], second[600];
    snprintf(first, sizeof first, "%s/a.mtl", folder);
    snprintf(second, sizeof second, "%s/b.mtl", folder);
    unlink(second);
    assert_int_equal(link(first, second), 0);
    write_text(folder, "m.obj", "mtllib a.mtl ./a.mtl\nmtllib b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n");
    lk_scene scene;
    lk_error error;
    assert_int_equal(read_scene(lk_test_path(folder, "m.obj"), &scene, &error), LK_OK);
    assert_int_equal(scene.material_count, 1);
    assert_color(scene.materials[0].base_color, 1, 0, 0, 1);
    if (scene.notes) fail_msg("notes: %s", scene.notes); /* no "defined again" */
    lk_scene_free(&scene);
}

/* A budget that holds the model but not its texture: a note, no texture. */
static void test_texture_budget(void **state)
{
    (void)state;
    const char *folder = make_folder("budget");
    size_t big = 256 * 1024;
    unsigned char *image = calloc(big, 1);
    assert_non_null(image);
    memcpy(image, png_bytes, sizeof png_bytes);
    lk_test_write_file(lk_test_path(folder, "big.png"), image, big);
    free(image);
    write_text(folder, "m.mtl", "newmtl big\nmap_Kd big.png\n");
    write_text(folder, "m.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl big\nf 1 2 3\n");
    lk_read_options options = {.max_bytes = 128 * 1024};
    lk_scene scene;
    lk_error error = {0};
    assert_int_equal(lk_scene_read(lk_test_path(folder, "m.obj"), &options, &scene, &error), LK_OK);
    assert_int_equal(scene.image_count, 0);
    assert_true(has_note(&scene, "do not fit the memory budget"));
    lk_scene_free(&scene);
    options.max_bytes = 1024 * 1024;
    assert_int_equal(lk_scene_read(lk_test_path(folder, "m.obj"), &options, &scene, &error), LK_OK);
    assert_int_equal(scene.image_count, 1);
    assert_int_equal(scene.images[0].size, big);
    lk_scene_free(&scene);
}

/* From memory there is no folder: the split by material stays, the .mtl
 * is a note. */
static void test_memory(void **state)
{
    (void)state;
    const char *text = "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                       "usemtl red\nf 1 2 3\nusemtl blue\nf 2 4 3\nusemtl red\nf 1 2 4\n";
    lk_scene scene;
    lk_error error = {0};
    assert_int_equal(lk_scene_read_memory(text, strlen(text), "mem.obj", NULL, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), 2);
    assert_int_equal(scene.meshes[0].primitives[0].mesh.triangle_count, 2);
    assert_string_equal(scene.materials[0].name, "red");
    assert_true(has_note(&scene, "mtllib a.mtl not read (reading from memory"));
    lk_scene_free(&scene);

    /* No faces: the mesh reader's point cloud, as before. */
    const char *points = "v 0 0 0\nvn 0 0 1\nv 1 0 0\nvn 0 0 1\n";
    assert_int_equal(lk_scene_read_memory(points, strlen(points), "points.obj", NULL, &scene, &error), LK_OK);
    assert_int_equal(primitive_count(&scene), 1);
    assert_int_equal(scene.meshes[0].primitives[0].mesh.vertex_count, 2);
    assert_int_equal(scene.meshes[0].primitives[0].mesh.triangle_count, 0);
    assert_non_null(scene.meshes[0].primitives[0].mesh.normals);
    lk_scene_free(&scene);
}

/* Malformed statements in the .obj or the .mtl: errors with file:line and
 * an empty scene. (An .obj without usemtl is the mesh reader's; so is
 * its .mtl, unread: nothing in it is used.) */
static void test_errors(void **state)
{
    (void)state;
    const char *folder = make_folder("errors");
    static const struct {
        const char *mtl, *obj, *message;
    } cases[] = {
        {"newmtl a\nKd red\n", "mtllib e.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
         "e.mtl:2: expected a colour 'r [g b]' after 'Kd'"},
        {"newmtl a\nNs\n", "mtllib e.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
         "e.mtl:2: expected a number after 'Ns'"},
        {"newmtl a\nd 1 x\n", "mtllib e.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
         "e.mtl:2: unexpected 'x'"},
        {"newmtl a\nmap_Kd -s 1\n", "mtllib e.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
         "e.mtl:2: expected a file name after 'map_Kd'"},
        {"newmtl a\n", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 x\n", "e.obj:5: expected a face corner"},
        {"newmtl a\n", "usemtl a\nv 0 0 0\nv 1 0 0\nf 1 2 -3\n", "e.obj:4: vertex index -3 out of range"},
        {"newmtl a\n", "usemtl a\nv 0 0 0\nv 1 0 0\nf 1 2 4\n", "e.obj:4: vertex index 4 out of range"},
        {"newmtl a\n", "usemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/5 2 3\n",
         "e.obj:5: texture coordinate index 5 out of range"},
        {"newmtl a\n", "usemtl a\n", "no vertices"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        write_text(folder, "e.mtl", cases[i].mtl);
        write_text(folder, "e.obj", cases[i].obj);
        lk_scene scene;
        lk_error error;
        assert_int_not_equal(read_scene(lk_test_path(folder, "e.obj"), &scene, &error), LK_OK);
        if (!strstr(error.message, cases[i].message)) fail_msg("case %zu: '%s'", i, error.message);
        assert_int_equal(scene.node_count, 0);
        assert_null(scene.nodes);
        assert_null(scene.notes);
    }
}

/* ---- drawing --------------------------------------------------------------- */

#define SIZE 160u

static unsigned char *draw(lk_renderer *renderer, const lk_scene *scene, const lk_render_options *options,
                           lk_render_scene_info *info)
{
    lk_error error = {0};
    lk_render_stats stats;
    if (lk_render_scene(renderer, scene, options, &stats, info, &error) != LK_OK)
        fail_msg("lk_render_scene: %s", error.message);
    unsigned char *rgba = malloc(SIZE * SIZE * 4);
    assert_non_null(rgba);
    assert_int_equal(lk_renderer_read_pixels(renderer, rgba, &error), LK_OK);
    return rgba;
}

/* Mean difference (0..255, over r g b) of the pixels both pictures cover
 * (the background is white). */
static double difference(const unsigned char *a, const unsigned char *b)
{
    double sum = 0;
    size_t both = 0;
    for (size_t i = 0; i < SIZE * SIZE; i++) {
        const unsigned char *p = a + 4 * i, *q = b + 4 * i;
        bool background = (p[0] == 255 && p[1] == 255 && p[2] == 255) || (q[0] == 255 && q[1] == 255 && q[2] == 255);
        if (background) continue;
        both++;
        for (int c = 0; c < 3; c++) sum += abs((int)p[c] - (int)q[c]) / 3.0;
    }
    assert_true(both > SIZE * SIZE / 20);
    return sum / (double)both;
}

/* spider.obj drawn from its .obj and from the .glb written from it look
 * the same: the textures are drawn with the same mapping (v is flipped once
 * by the writer, once by the reader). Controls: the same scene without its
 * textures, and with v flipped in lodkit's coordinates, look different. */
static void test_spider_drawn_textured(void **state)
{
    (void)state;
    lk_renderer *renderer = NULL;
    lk_error error = {0};
    if (lk_renderer_create(SIZE, SIZE, &renderer, &error) != LK_OK) fail_msg("lk_renderer_create: %s", error.message);
    lk_scene scene, back;
    assert_int_equal(read_scene(lk_test_sample(OBJ_DIR "spider.obj"), &scene, &error), LK_OK);
    const char *glb = lk_test_tmpfile("spider.glb");
    assert_int_equal(lk_scene_write(glb, &scene, NULL, &error), LK_OK);
    assert_int_equal(read_scene(glb, &back, &error), LK_OK);
    lk_render_options options;
    lk_render_options_default(&options);
    lk_render_scene_info info;
    unsigned char *from_obj = draw(renderer, &scene, &options, &info);
    assert_int_equal(info.materials, 4);
    assert_int_equal(info.textures_drawn, 4);
    assert_int_equal(info.textures_failed, 0);
    unsigned char *from_glb = draw(renderer, &back, &options, &info);
    assert_int_equal(info.textures_drawn, 4);
    double same = difference(from_obj, from_glb);

    lk_scene flipped;
    assert_int_equal(lk_scene_copy(&flipped, &scene, &error), LK_OK);
    for (size_t p = 0; p < flipped.meshes[0].primitive_count; p++) {
        lk_mesh *mesh = &flipped.meshes[0].primitives[p].mesh;
        for (size_t v = 0; v < mesh->vertex_count; v++) mesh->texcoords[2 * v + 1] = 1.0f - mesh->texcoords[2 * v + 1];
    }
    unsigned char *upside_down = draw(renderer, &flipped, &options, &info);
    for (size_t m = 0; m < scene.material_count; m++) scene.materials[m].base_color_texture = -1;
    unsigned char *untextured = draw(renderer, &scene, &options, &info);
    assert_int_equal(info.textures_drawn, 0);
    double flip = difference(from_obj, upside_down), plain = difference(from_obj, untextured);
    print_message("mean difference to the .obj's picture: .glb %.2f, v flipped %.2f, untextured %.2f\n", same, flip,
                  plain);
    assert_true(same < 2.0);
    assert_true(flip > 4 * same && flip > 3.0);
    assert_true(plain > 4 * same && plain > 3.0);
    free(from_obj), free(from_glb), free(upside_down), free(untextured);
    lk_scene_free(&flipped);
    lk_scene_free(&back);
    lk_scene_free(&scene);
    lk_renderer_free(renderer);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spider),          cmocka_unit_test(test_assimp_material_files),
        cmocka_unit_test(test_built_materials), cmocka_unit_test(test_same_mtl_once),
        cmocka_unit_test(test_texture_budget),  cmocka_unit_test(test_memory),
        cmocka_unit_test(test_errors),          cmocka_unit_test(test_spider_drawn_textured),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
