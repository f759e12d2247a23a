/* SPDX-License-Identifier: MIT */
/* lodkit formats: the library's format table (lk_format_info_at) as a
 * list, grouped by what lodkit reads the files as, or as JSON. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"

const cli_help formats_help = {
    "",
    "List the file formats lodkit knows, by extension: the library's format\n"
    "table, grouped by what lodkit reads a file as (r: read, w: written). A\n"
    "format may be in two groups: glTF holds a mesh and its animations.\n",
    NULL,
};

/* The groups, one per LK_IO_ flag, and the commands that take them. */
static const struct {
    unsigned io;
    const char *title;    /* before the commands */
    const char *commands; /* NULL: those that read meshes */
    const char *note;     /* after the commands, or "" */
    const char *key;      /* in the JSON */
} groups[] = {
    {LK_IO_MESH, "Meshes and point sets", NULL, "; of an animation, frame 0", "mesh"},
    {LK_IO_ANIMATION, "Animations", "animate", "", "animation"},
    {LK_IO_GRID, "Elevation grids", "info, terrain", "", "grid"},
    {LK_IO_STREAM, "Progressive streams", "inspect, unpack", "; progressive writes them", "stream"},
};
#define GROUP_COUNT (sizeof groups / sizeof groups[0])

/* "Title (command, command; note):", wrapped. */
static void print_group_title(size_t g)
{
    char title[512];
    size_t used = (size_t)snprintf(title, sizeof title, "%s (", groups[g].title);
    if (groups[g].commands) {
        used += (size_t)snprintf(title + used, sizeof title - used, "%s", groups[g].commands);
    } else {
        /* the commands that read meshes are those that take --weld */
        const char *separator = "";
        for (int c = 0; c < CMD_MAIN && used < sizeof title; c++)
            if (cli_takes((cli_command_id)c, OPT_WELD)) {
                used += (size_t)snprintf(title + used, sizeof title - used, "%s%s", separator, cli_commands[c].name);
                separator = ", ";
            }
    }
    if (used < sizeof title) snprintf(title + used, sizeof title - used, "%s):", groups[g].note);
    print_wrapped(stdout, title, 0, 4);
}

static void print_table(void)
{
    const lk_format_info *info;
    for (size_t g = 0; g < GROUP_COUNT; g++) {
        if (g) putchar('\n');
        print_group_title(g);
        for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
            if (!(info->read & groups[g].io) && !(info->write & groups[g].io)) continue;
            char mode[3] = "  ";
            if (info->read & groups[g].io) mode[0] = 'r';
            if (info->write & groups[g].io) mode[1] = 'w';
            int length = printf("  %-16s %s ", info->extensions, mode);
            if (length > 22) { /* a long list of extensions: the description below it */
                putchar('\n');
                length = printf("%22s", "");
            }
            print_wrapped(stdout, info->description, length, 22);
        }
    }
}

static cJSON *io_array(unsigned flags)
{
    cJSON *array = cJSON_CreateArray();
    for (size_t g = 0; g < GROUP_COUNT; g++)
        if (flags & groups[g].io) cJSON_AddItemToArray(array, cJSON_CreateString(groups[g].key));
    return array;
}

static void print_table_json(void)
{
    cJSON *root = cJSON_CreateObject();
    cJSON *formats = cJSON_AddArrayToObject(root, "formats");
    const lk_format_info *info;
    for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
        cJSON *entry = cJSON_CreateObject();
        cJSON_AddStringToObject(entry, "name", info->name);
        cJSON *extensions = cJSON_AddArrayToObject(entry, "extensions");
        for (const char *word = info->extensions; *word;) {
            size_t length = strcspn(word, " ");
            char extension[64];
            snprintf(extension, sizeof extension, "%.*s", (int)length, word);
            cJSON_AddItemToArray(extensions, cJSON_CreateString(extension));
            word += length;
            word += strspn(word, " ");
        }
        cJSON_AddStringToObject(entry, "kind", lk_format_kind_name(info->kind));
        cJSON_AddItemToObject(entry, "read", io_array(info->read));
        cJSON_AddItemToObject(entry, "write", io_array(info->write));
        cJSON_AddStringToObject(entry, "description", info->description);
        cJSON_AddItemToArray(formats, entry);
    }
    print_json(root);
}

int cmd_formats(int argc, char **argv)
{
    cli_parser parser;
    cli_parse_begin(&parser, CMD_FORMATS, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) return cli_unhandled(&parser, id);
    if (argc - optind != 0) return usage_error("formats", "unexpected argument '%s'", argv[optind]);
    if (parser.json)
        print_table_json();
    else
        print_table();
    return EXIT_OK;
}
