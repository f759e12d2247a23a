/* lodkit info: the size, bounds and topology of meshes and point sets. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "lodkit.h"


/* ---- info -------------------------------------------------------------- */

static const char info_help[] =
    "Usage: lodkit info [options] FILE...\n"
    "Print the size, bounds and topology of meshes and point sets.\n"
    "\n"
    "  --json        one JSON object per file (one per line)\n"
    "  -h, --help    show this help\n"
    CLI_MEMORY_HELP
    "\n"
    "With one FILE the report is a list; with several, a table with a row per file.\n"
    "Genus is -1 when the mesh is not a manifold (it is then undefined).\n";

static cJSON *stats_json(const char *path, const lk_mesh_stats *stats, double load_seconds)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddStringToObject(object, "file", path);
    cJSON_AddStringToObject(object, "format", lk_format_name(lk_format_from_path(path)));
    cJSON_AddNumberToObject(object, "vertices", (double)stats->vertex_count);
    cJSON_AddNumberToObject(object, "triangles", (double)stats->triangle_count);
    cJSON_AddNumberToObject(object, "used_vertices", (double)stats->used_vertex_count);
    cJSON_AddNumberToObject(object, "edges", (double)stats->edge_count);
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
        printf("boundary edges        %s (%s loops)\n", thousands(stats->boundary_edge_count),
               thousands(stats->boundary_loop_count));
        printf("non-manifold edges    %s\n", thousands(stats->nonmanifold_edge_count));
        printf("non-manifold vertices %s\n", thousands(stats->nonmanifold_vertex_count));
        printf("degenerate triangles  %s\n", thousands(stats->degenerate_triangle_count));
        printf("duplicate triangles   %s\n", thousands(stats->duplicate_triangle_count));
        printf("euler characteristic  %lld\n", stats->euler_characteristic);
        if (stats->genus >= 0) printf("genus                 %lld\n", stats->genus);
        else printf("genus                 undefined (not a manifold)\n");
    }
    printf("load time             %.1f ms\n", load_seconds * 1000);
}

static const char *short_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

int command_info(int argc, char **argv)
{
    static const struct option options[] = {{"json", no_argument, NULL, 'j'}, {"help", no_argument, NULL, 'h'}, {0}};
    int json = 0, option;
    while ((option = getopt_long(argc, argv, "h", options, NULL)) != -1) {
        switch (option) {
        case 'j': json = 1; break;
        case 'h': fputs(info_help, stdout); return EXIT_OK;
        default: return usage_error("info", "%s", "invalid option");
        }
    }
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
        if (load_mesh(argv[i], &mesh, &seconds, &error) != LK_OK ||
            lk_mesh_compute_stats(&mesh, &stats, &error) != LK_OK) {
            print_error_for(argv[i], NULL, &error);
            lk_mesh_free(&mesh);
            result = EXIT_BAD_INPUT;
            continue;
        }
        if (json) {
            print_json(stats_json(argv[i], &stats, seconds));
        } else if (file_count == 1) {
            print_stats_list(argv[i], &mesh, &stats, seconds);
        } else {
            char genus[24];
            if (stats.genus >= 0) snprintf(genus, sizeof genus, "%lld", stats.genus);
            else snprintf(genus, sizeof genus, "-");
            printf("%-24s %10s %10s %10.4g %5s %8s %8s %5s %9.1f\n", short_name(argv[i]),
                   thousands(stats.vertex_count), thousands(stats.triangle_count), stats.diagonal,
                   thousands(stats.component_count), thousands(stats.boundary_edge_count),
                   thousands(stats.nonmanifold_edge_count), genus, seconds * 1000);
        }
        lk_mesh_free(&mesh);
    }
    return result;
}
