/* SPDX-License-Identifier: MIT */
/* Error messages of the lodkit commands: every one names its file, and a
 * usage error says where the help is. */
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"

const char *program = "lodkit";

/* Does MESSAGE start with PATH, as "PATH:" or "PATH/..." (a file in it)? */
static bool names_file(const char *message, const char *path)
{
    size_t length = path ? strlen(path) : 0;
    return length && strncmp(message, path, length) == 0 && (message[length] == ':' || message[length] == '/');
}

void print_error_for(const char *input, const char *output, const lk_error *error)
{
    const char *message = error->message[0] ? error->message : lk_status_string(error->status);
    /* Say how to raise a budget the library refused against. */
    bool budget = error->status == LK_ERR_LIMIT && strstr(message, "memory budget") && !strstr(message, "--max-memory");
    bool named = !input || names_file(message, input) || names_file(message, output);
    fprintf(stderr, "%s: %s%s%s%s\n", program, named ? "" : input, named ? "" : ": ", message,
            budget ? " (--max-memory)" : "");
}

void print_error(const lk_error *error) { print_error_for(NULL, NULL, error); }

int usage_error(const char *command, const char *format, const char *detail)
{
    fprintf(stderr, "%s%s%s: ", program, command ? " " : "", command ? command : "");
    fprintf(stderr, format, detail);
    fprintf(stderr, "\nTry '%s %s%s--help' for more information.\n", program, command ? command : "",
            command ? " " : "");
    if (command) fputc('\n', stderr);
    return EXIT_USAGE;
}
