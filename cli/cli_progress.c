/* SPDX-License-Identifier: MIT */
/* The progress bar of long commands: on stderr when it is a terminal,
 * silent otherwise or with --quiet. */
#include <stdio.h>
#include <unistd.h>

#include "cli.h"

int progress_draw(void *user, double fraction, const char *stage)
{
    progress_state *state = user;
    if (!state->enabled) return 0;
    int permille = (int)(fraction * 1000);
    /* a new stage is shown even at the same fraction (a step that starts at 0) */
    if (permille == state->last_permille && stage == state->last_stage) return 0;
    state->last_permille = permille;
    state->last_stage = stage;
    int filled = (int)(fraction * 30);
    fprintf(stderr, "\r%s %-10s [", state->label, stage ? stage : "");
    for (int i = 0; i < 30; i++) fputc(i < filled ? '#' : ' ', stderr);
    fprintf(stderr, "] %5.1f%%", fraction * 100);
    if (fraction >= 1.0) fprintf(stderr, "\r\033[K");
    fflush(stderr);
    return 0;
}

void progress_init(progress_state *state, int quiet, const char *label)
{
    state->enabled = !quiet && isatty(STDERR_FILENO);
    state->last_permille = -1;
    state->last_stage = NULL;
    state->label = label;
}

void progress_done(progress_state *state)
{
    if (state->enabled && state->last_permille >= 0) fprintf(stderr, "\r\033[K");
}
