/* SPDX-License-Identifier: MIT */
/* The CLI names the file formats from the library's format table: with the
 * table (lk_format_info_at) as the truth, `lodkit formats` (text and JSON)
 * lists every entry, and each help text and message that lists formats
 * names exactly the extensions of the formats it is about (convert's Read
 * and Write lines, info, unpack, terrain, animate, the refusal of an
 * output extension), so a format added to the table and missing from the
 * CLI fails here. Runs the built lodkit (LK_BUILD_DIR). */
#include <cjson/cJSON.h>
#include <ctype.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "testutil.h"

/* Runs `lodkit ARGS` (stderr too) and returns what it printed (malloc'ed). */
static char *run(const char *args, int *exit_code)
{
    char command[2048];
    snprintf(command, sizeof command, "'%s/lodkit' %s 2>&1", LK_BUILD_DIR, args);
    FILE *pipe = popen(command, "r");
    assert_non_null(pipe);
    size_t capacity = 1 << 14, size = 0;
    char *text = malloc(capacity);
    assert_non_null(text);
    for (size_t n; (n = fread(text + size, 1, capacity - size - 1, pipe)) > 0;) {
        size += n;
        if (size + 1 == capacity) {
            capacity *= 2;
            text = realloc(text, capacity);
            assert_non_null(text);
        }
    }
    text[size] = '\0';
    int status = pclose(pipe);
    if (exit_code) *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return text;
}

/* What a list is about: a format belongs to it when this says so. */
typedef bool (*belongs_fn)(const lk_format_info *info);

static bool reads_mesh(const lk_format_info *info) { return info->read & LK_IO_MESH; }
static bool writes_mesh(const lk_format_info *info) { return info->write & LK_IO_MESH; }
static bool writes_triangles(const lk_format_info *info)
{
    return (info->write & LK_IO_MESH) && info->kind != LK_FORMAT_KIND_POINTS;
}
static bool reads_animation(const lk_format_info *info) { return info->read & LK_IO_ANIMATION; }
static bool reads_grid(const lk_format_info *info) { return info->read & LK_IO_GRID; }

/* The extensions of the formats that belong, in the table's order, each
 * preceded by `prefix` ("" or "."), separated by one space. */
static void expected_list(belongs_fn belongs, const char *prefix, char *out, size_t size)
{
    size_t used = 0;
    out[0] = '\0';
    const lk_format_info *info;
    for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
        if (!belongs(info)) continue;
        for (const char *word = info->extensions; *word;) {
            size_t length = strcspn(word, " ");
            used += (size_t)snprintf(out + used, size - used, "%s%s%.*s", used ? " " : "", prefix, (int)length, word);
            assert_true(used < size);
            word += length;
            if (*word == ' ') word++;
        }
    }
}

/* True when `word` occurs in text as a whole word (not inside another). */
static bool has_word(const char *text, const char *word)
{
    size_t length = strlen(word);
    for (const char *p = strstr(text, word); p; p = strstr(p + 1, word)) {
        bool start = p == text || !(isalnum((unsigned char)p[-1]) || p[-1] == '.' || p[-1] == '_');
        bool end = !(isalnum((unsigned char)p[length]) || p[length] == '_');
        if (start && end) return true;
    }
    return false;
}

/* Every extension of the formats that belong is a word of text. */
static void assert_all_named(const char *what, const char *text, belongs_fn belongs)
{
    char list[2048];
    expected_list(belongs, "", list, sizeof list);
    assert_true(list[0]);
    for (char *word = strtok(list, " "); word; word = strtok(NULL, " "))
        if (!has_word(text, word)) fail_msg("%s does not name .%s:\n%s", what, word, text);
}

/* The rest of the line after `label` in text, with wrapped lines joined
 * (static buffer). */
static const char *line_after(const char *text, const char *label)
{
    static char line[2048];
    const char *start = strstr(text, label);
    if (!start) fail_msg("no '%s' in:\n%s", label, text);
    start += strlen(label);
    size_t length = strcspn(start, "\n");
    assert_true(length < sizeof line);
    memcpy(line, start, length);
    line[length] = '\0';
    return line;
}

static void test_formats_command(void **state)
{
    (void)state;
    int code;
    char *text = run("formats", &code);
    assert_int_equal(code, 0);
    const lk_format_info *info;
    size_t count = 0;
    for (size_t i = 0; (info = lk_format_info_at(i)); i++, count++) {
        /* a row "  EXTENSIONS  MODE DESCRIPTION..." under each of its groups */
        char row[256];
        snprintf(row, sizeof row, "\n  %s ", info->extensions);
        if (!strstr(text, row))
            fail_msg("lodkit formats has no row for %s (%s):\n%s", info->name, info->extensions, text);
        char first_words[64];
        snprintf(first_words, sizeof first_words, "%.20s", info->description);
        if (!strstr(text, first_words)) fail_msg("lodkit formats does not describe %s", info->name);
    }
    free(text);

    text = run("formats --json", &code);
    assert_int_equal(code, 0);
    cJSON *json = cJSON_Parse(text);
    assert_non_null(json);
    const cJSON *formats = cJSON_GetObjectItemCaseSensitive(json, "formats");
    assert_int_equal((size_t)cJSON_GetArraySize(formats), count);
    for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
        const cJSON *entry = cJSON_GetArrayItem(formats, (int)i);
        assert_string_equal(cJSON_GetObjectItemCaseSensitive(entry, "name")->valuestring, info->name);
        assert_string_equal(cJSON_GetObjectItemCaseSensitive(entry, "kind")->valuestring,
                            lk_format_kind_name(info->kind));
        char joined[256] = "";
        const cJSON *extension;
        cJSON_ArrayForEach(extension, cJSON_GetObjectItemCaseSensitive(entry, "extensions"))
        {
            if (joined[0]) strcat(joined, " ");
            strcat(joined, extension->valuestring);
        }
        assert_string_equal(joined, info->extensions);
        const cJSON *read = cJSON_GetObjectItemCaseSensitive(entry, "read");
        assert_int_equal(cJSON_GetArraySize(read), __builtin_popcount(info->read));
    }
    cJSON_Delete(json);
    free(text);

    text = run("--help", &code);
    assert_int_equal(code, 0);
    assert_non_null(strstr(text, "\n  formats "));
    free(text);
}

static void test_help_lists(void **state)
{
    (void)state;
    char expected[2048];
    /* convert: exactly the formats lk_mesh_read reads and lk_mesh_write writes */
    char *text = run("convert --help", NULL);
    expected_list(reads_mesh, "", expected, sizeof expected);
    assert_string_equal(line_after(text, "\nRead: "), expected);
    expected_list(writes_mesh, "", expected, sizeof expected);
    assert_string_equal(line_after(text, "\nWrite: "), expected);
    free(text);

    text = run("info --help", NULL);
    assert_all_named("info --help", text, reads_mesh);
    assert_all_named("info --help", text, reads_grid);
    free(text);
    text = run("terrain --help", NULL);
    assert_all_named("terrain --help", text, reads_grid);
    free(text);
    text = run("animate --help", NULL);
    assert_all_named("animate --help", text, reads_animation);
    free(text);
    text = run("unpack --help", NULL);
    assert_all_named("unpack --help", text, writes_triangles);
    free(text);
}

static void test_output_messages(void **state)
{
    (void)state;
    lk_mesh cube;
    lk_test_make_cube(&cube);
    lk_error error = {0};
    const char *input = lk_test_tmpfile("cube.obj");
    assert_int_equal(lk_mesh_write(input, LK_FORMAT_OBJ, &cube, NULL, &error), LK_OK);
    lk_mesh_free(&cube);
    char args[1024], expected[2048];
    int code;

    /* convert writes point sets too; simplify only triangles */
    snprintf(args, sizeof args, "convert '%s' '%s'", input, lk_test_tmpfile("out.unknownext"));
    char *text = run(args, &code);
    assert_int_equal(code, 2);
    expected_list(writes_mesh, ".", expected, sizeof expected);
    char *last_space = strrchr(expected, ' ');
    assert_non_null(last_space);
    char dotted[2100];
    snprintf(dotted, sizeof dotted, "use %.*s or %s\n", (int)(last_space - expected), expected, last_space + 1);
    if (!strstr(text, dotted)) fail_msg("convert's refusal does not say '%s':\n%s", dotted, text);
    free(text);

    snprintf(args, sizeof args, "simplify -r 0.5 '%s' '%s'", input, lk_test_tmpfile("out.pts"));
    text = run(args, &code);
    assert_int_equal(code, 2);
    expected_list(writes_triangles, ".", expected, sizeof expected);
    last_space = strrchr(expected, ' ');
    snprintf(dotted, sizeof dotted, "use %.*s or %s\n", (int)(last_space - expected), expected, last_space + 1);
    if (!strstr(text, dotted)) fail_msg("simplify's refusal does not say '%s':\n%s", dotted, text);
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_formats_command),
        cmocka_unit_test(test_help_lists),
        cmocka_unit_test(test_output_messages),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
