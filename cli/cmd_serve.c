/* SPDX-License-Identifier: MIT */
/* lodkit serve: the embedded HTTP server (src/serve/) for a directory of
 * streams, point sets and terrains, with the WebGL viewer. */
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help serve_help = {
    "DIR",
    "Serve DIR over HTTP with the WebGL viewer (docs/server.md):\n"
    "  /                 the viewer (compiled in; see --web)\n"
    "  /m/PATH           the files of DIR, with Range requests, ETags, gzip for text\n"
    "  /api/index.json   the models in DIR: streams, meshes, point sets, terrains\n"
    "  /api/points/PATH  a point set as an LKMB buffer with normals and radii\n"
    "  /api/terrain/PATH?eye=x,y,z&target=x,y,z  the CLOD terrain mesh for one view\n"
    "Prints 'lodkit serve: serving DIR at http://HOST:PORT/' once listening, then\n"
    "one line per request on stderr; SIGINT or SIGTERM stop it (exit 0).\n",
    NULL,
};

static void log_line(void *user, const char *line)
{
    (void)user;
    fprintf(stderr, "%s\n", line);
}

int cmd_serve(int argc, char **argv)
{
    lk_server_options server_options;
    lk_server_options_default(&server_options);
    server_options.log = log_line;
    /* --max-memory (taken out of argv by main) bounds each file the server parses. */
    server_options.max_memory = cli_max_memory;
    if (server_options.max_file_bytes > cli_max_memory) server_options.max_file_bytes = cli_max_memory;
    size_t value;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_SERVE, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_PORT:
            if (!parse_size_option(arg, &value) || value > 65535)
                return usage_error("serve", "--port: '%s' is not a port from 0 to 65535", arg);
            server_options.port = (unsigned)value;
            break;
        case OPT_HOST:
            if (!arg[0]) return usage_error("serve", "--host: '%s' is empty", arg);
            server_options.host = arg;
            break;
        case OPT_SIMPLIFY_ON_DEMAND: server_options.simplify_on_demand = 1; break;
        case OPT_CACHE: server_options.cache_dir = arg; break;
        case OPT_WEB: server_options.web_dir = arg; break;
        case OPT_MAX_CONNECTIONS:
            if (!parse_size_option(arg, &value) || value < 1 || value > 100000)
                return usage_error("serve", "--max-connections: '%s' is not a count from 1 to 100000", arg);
            server_options.max_connections = (unsigned)value;
            if (server_options.max_connections_per_ip > server_options.max_connections)
                server_options.max_connections_per_ip = server_options.max_connections;
            break;
        case OPT_TIMEOUT:
            if (!parse_size_option(arg, &value) || value < 1 || value > 86400)
                return usage_error("serve", "--timeout: '%s' is not a number of seconds from 1 to 86400", arg);
            server_options.timeout_seconds = (unsigned)value;
            break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int quiet = parser.quiet;
    if (argc - optind != 1) return usage_error("serve", "%s", "expected one directory");
    const char *directory = argv[optind];
    if (quiet) server_options.log = NULL;

    /* The server's threads inherit this mask, so SIGINT/SIGTERM reach
     * sigwait below and nowhere else; a client that disconnects while a
     * file is sent must not kill the process with SIGPIPE. */
    signal(SIGPIPE, SIG_IGN);
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, NULL);

    lk_server *server = NULL;
    lk_error error = {0};
    if (lk_server_start(directory, &server_options, &server, &error) != LK_OK) {
        print_error_for(directory, NULL, &error);
        return EXIT_BAD_INPUT;
    }
    const char *host = server_options.host;
    int ipv6 = strchr(host, ':') != NULL;
    printf("lodkit serve: serving %s at http://%s%s%s:%u/\n", directory, ipv6 ? "[" : "", host, ipv6 ? "]" : "",
           lk_server_port(server));
    fflush(stdout);
    int received = 0;
    sigwait(&stop_signals, &received);
    if (!quiet) fprintf(stderr, "lodkit serve: %s, stopping\n", received == SIGINT ? "SIGINT" : "SIGTERM");
    lk_server_stop(server);
    return EXIT_OK;
}
