/* SPDX-License-Identifier: MIT */
/* Acclaim skeleton (ASF), Acclaim motion (AMC) and lodkit's bone weights
 * (WGT); docs/formats.md defines what is accepted. All three are line-based
 * text; every error names FILE:LINE.
 *
 * ASF sections (a ':' keyword at the start of a line):
 *   :units       mass M / length L / angle deg|rad
 *   :root        order <dofs>, axis <XYZ order>, position x y z, orientation a b c
 *   :bonedata    begin / id / name / direction / length / axis a b c ORDER /
 *                dof <rx ry rz tx ty tz l ...> / limits (lo hi) per dof / end
 *   :hierarchy   begin / PARENT CHILD... / end
 *   others (:version, :name, :documentation, ...) are skipped.
 * Bones are stored parents first (root = 0), whatever the file order.
 *
 * AMC: optional comments and ':' keywords (:FULLY-SPECIFIED, :DEGREES,
 * :RADIANS), then frames: a line holding the frame number (1, 2, 3, ...
 * consecutive), followed by one line "BONE v1 v2 ..." per bone that has
 * channels, with exactly that bone's dof count of values. */
#include "anim_io.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define ACCLAIM_MAX_BONES 4096u
#define ACCLAIM_MAX_NAME 63u
#define ACCLAIM_MAX_FRAMES ((size_t)1 << 22)

/* ---- line tokenizer ------------------------------------------------------ */

typedef struct text_cursor {
    const char *p, *end;
    size_t line;                       /* number of the line last returned */
    const char *line_start, *line_end; /* current line, comment and trailing spaces cut */
} text_cursor;

/* Advances to the next line that is not blank or a comment. */
static bool next_line(text_cursor *cursor)
{
    while (cursor->p < cursor->end) {
        const char *newline = memchr(cursor->p, '\n', (size_t)(cursor->end - cursor->p));
        const char *line_end = newline ? newline : cursor->end;
        const char *start = lk__skip_spaces(cursor->p, line_end);
        cursor->p = newline ? newline + 1 : cursor->end;
        cursor->line++;
        const char *comment = memchr(start, '#', (size_t)(line_end - start));
        if (comment) line_end = comment;
        while (line_end > start && lk__is_space(line_end[-1])) line_end--;
        if (start == line_end) continue;
        cursor->line_start = start;
        cursor->line_end = line_end;
        return true;
    }
    return false;
}

/* Next whitespace-separated token of the current line from *p. */
static bool next_token(const char **p, const char *end, const char **token, size_t *length)
{
    const char *q = lk__skip_spaces(*p, end);
    *token = end;
    *length = 0;
    if (q >= end) return false;
    const char *t = q;
    while (q < end && !lk__is_space(*q)) q++;
    *token = t;
    *length = (size_t)(q - t);
    *p = q;
    return true;
}

static bool token_is(const char *token, size_t length, const char *word)
{
    return lk__word_equals(token, length, word);
}

/* ---- ASF ----------------------------------------------------------------- */

typedef struct asf_bone_entry {
    lk_bone bone;
    size_t line;     /* where it was defined */
    long parent_raw; /* index in file order; -1 = root, -2 = unset */
} asf_bone_entry;

static lk_status parse_dof(const char *token, size_t length, lk_dof *dof)
{
    static const char *const names[] = {"tx", "ty", "tz", "rx", "ry", "rz", "l"};
    for (int i = 0; i < 7; i++)
        if (token_is(token, length, names[i])) {
            *dof = (lk_dof)i;
            return LK_OK;
        }
    return LK_ERR_PARSE;
}

static bool parse_axis_order(const char *token, size_t length, char out[4])
{
    if (length != 3) return false;
    bool seen[3] = {false, false, false};
    for (int i = 0; i < 3; i++) {
        char c = token[i] >= 'a' ? (char)(token[i] - 32) : token[i];
        if (c < 'X' || c > 'Z' || seen[c - 'X']) return false;
        seen[c - 'X'] = true;
        out[i] = c;
    }
    out[3] = '\0';
    return true;
}

static lk_status read_numbers(const char **p, const char *end, double *out, int count, const char *name, size_t line,
                              const char *what, lk_error *error)
{
    for (int i = 0; i < count; i++) {
        if (!lk__parse_double(p, end, &out[i]))
            return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected %d numbers after '%s'", count, what);
        if (!isfinite(out[i]))
            return lk__error_at_line(error, LK_ERR_RANGE, name, line, "'%s' value is not finite", what);
    }
    return LK_OK;
}

static lk_status expect_end_of_line(const char *p, const char *end, const char *name, size_t line, const char *what,
                                    lk_error *error)
{
    if (lk__skip_spaces(p, end) != end) {
        char token[32];
        lk__quote_token(p, end, token, sizeof token);
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "unexpected '%s' after '%s'", token, what);
    }
    return LK_OK;
}

/* Parses "(lo hi)" possibly followed by more limits on the same line. */
static lk_status parse_limit(const char **p, const char *end, double out[2], const char *name, size_t line,
                             lk_error *error)
{
    const char *q = lk__skip_spaces(*p, end);
    if (q >= end || *q != '(') return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected '(min max)' limit");
    q++;
    for (int i = 0; i < 2; i++) {
        if (!lk__parse_double(&q, end, &out[i]) || isnan(out[i]))
            return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected '(min max)' limit");
    }
    q = lk__skip_spaces(q, end);
    if (q >= end || *q != ')')
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected ')' to close a limit");
    *p = q + 1;
    return LK_OK;
}

static long find_entry(const asf_bone_entry *entries, size_t count, const char *token, size_t length)
{
    for (size_t i = 0; i < count; i++)
        if (strlen(entries[i].bone.name) == length && memcmp(entries[i].bone.name, token, length) == 0) return (long)i;
    return -2;
}

static lk_status asf_read_bone(text_cursor *cursor, const char *name, asf_bone_entry *entry, lk_error *error)
{
    lk_bone *bone = &entry->bone;
    memset(entry, 0, sizeof *entry);
    entry->line = cursor->line;
    entry->parent_raw = -2;
    strcpy(bone->axis_order, "XYZ");
    for (int k = 0; k < 7; k++) bone->limits[k][0] = -INFINITY, bone->limits[k][1] = INFINITY;
    bool have_direction = false, have_length = false;
    size_t limits_read = 0;
    bool in_limits = false;
    while (next_line(cursor)) {
        const char *p = cursor->line_start, *end = cursor->line_end, *token = NULL;
        size_t length = 0, line = cursor->line;
        lk_status status;
        if (in_limits && *lk__skip_spaces(p, end) == '(') {
            /* Continuation lines of `limits`. */
            while (lk__skip_spaces(p, end) < end) {
                if (limits_read >= bone->dof_count)
                    return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                             "more limits than dofs (%u) for bone '%s'", bone->dof_count, bone->name);
                if ((status = parse_limit(&p, end, bone->limits[limits_read], name, line, error)) != LK_OK)
                    return status;
                limits_read++;
            }
            continue;
        }
        in_limits = false;
        next_token(&p, end, &token, &length);
        if (token_is(token, length, "end")) {
            if (!bone->name[0]) return lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone without a name");
            if (!have_direction || !have_length)
                return lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' lacks a direction or a length",
                                         bone->name);
            if (limits_read && limits_read != bone->dof_count)
                return lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' has %zu limits for %u dofs",
                                         bone->name, limits_read, bone->dof_count);
            double norm = sqrt(bone->direction[0] * bone->direction[0] + bone->direction[1] * bone->direction[1] +
                               bone->direction[2] * bone->direction[2]);
            if (norm > 0)
                for (int k = 0; k < 3; k++) bone->direction[k] /= norm;
            return LK_OK;
        }
        if (token_is(token, length, "name")) {
            if (!next_token(&p, end, &token, &length))
                return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected a bone name");
            if (length > ACCLAIM_MAX_NAME)
                return lk__error_at_line(error, LK_ERR_LIMIT, name, line, "bone name longer than %u characters",
                                         ACCLAIM_MAX_NAME);
            memcpy(bone->name, token, length);
            bone->name[length] = '\0';
            if ((status = expect_end_of_line(p, end, name, line, "name", error)) != LK_OK) return status;
        } else if (token_is(token, length, "direction")) {
            if ((status = read_numbers(&p, end, bone->direction, 3, name, line, "direction", error)) != LK_OK)
                return status;
            have_direction = true;
        } else if (token_is(token, length, "length")) {
            if ((status = read_numbers(&p, end, &bone->length, 1, name, line, "length", error)) != LK_OK) return status;
            if (bone->length < 0)
                return lk__error_at_line(error, LK_ERR_RANGE, name, line, "negative bone length %g", bone->length);
            have_length = true;
        } else if (token_is(token, length, "axis")) {
            if ((status = read_numbers(&p, end, bone->axis, 3, name, line, "axis", error)) != LK_OK) return status;
            if (!next_token(&p, end, &token, &length) || !parse_axis_order(token, length, bone->axis_order))
                return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                         "expected a rotation order such as XYZ after the axis angles");
        } else if (token_is(token, length, "dof")) {
            while (next_token(&p, end, &token, &length)) {
                lk_dof dof;
                if (parse_dof(token, length, &dof) != LK_OK) {
                    char quoted[32];
                    lk__quote_token(token, end, quoted, sizeof quoted);
                    return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                             "unknown dof '%s' (expected rx ry rz tx ty tz l)", quoted);
                }
                if (bone->dof_count == 7) return lk__error_at_line(error, LK_ERR_PARSE, name, line, "more than 7 dofs");
                bone->dof[bone->dof_count++] = dof;
            }
        } else if (token_is(token, length, "limits")) {
            in_limits = true;
            while (lk__skip_spaces(p, end) < end) {
                if (limits_read >= bone->dof_count)
                    return lk__error_at_line(error, LK_ERR_PARSE, name, line, "more limits than dofs (%u)",
                                             bone->dof_count);
                if ((status = parse_limit(&p, end, bone->limits[limits_read], name, line, error)) != LK_OK)
                    return status;
                limits_read++;
            }
        } else if (token_is(token, length, "begin") || *token == ':') {
            return lk__error_at_line(error, LK_ERR_PARSE, name, line, "missing 'end' of the bone begun at line %zu",
                                     entry->line);
        }
        /* id, bodymass, cofmass and other keys are not needed. */
    }
    return lk__error_at_line(error, LK_ERR_PARSE, name, cursor->line, "file ends inside a bone (begun at line %zu)",
                             entry->line);
}

lk_status lk_skeleton_read_memory(const char *data, size_t size, const char *name, lk_skeleton *skeleton,
                                  lk_error *error)
{
    if (!skeleton) return lk_error_set(error, LK_ERR_INVALID, "NULL skeleton");
    memset(skeleton, 0, sizeof *skeleton);
    if (!name) name = "<memory>";
    if (!data || size == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: empty file", name);
    text_cursor cursor = {data, data + size, 0, NULL, NULL};
    lk__buffer entries_buffer = {0};
    asf_bone_entry root;
    memset(&root, 0, sizeof root);
    strcpy(root.bone.name, "root");
    strcpy(root.bone.axis_order, "XYZ");
    root.parent_raw = -1;
    for (int k = 0; k < 7; k++) root.bone.limits[k][0] = -INFINITY, root.bone.limits[k][1] = INFINITY;
    /* Default root channels when :root has no `order`. */
    bool have_root = false, have_hierarchy = false;
    double length_unit = 1;
    int radians = 0;
    enum { NONE, UNITS, ROOT, BONEDATA, HIERARCHY, OTHER } section = NONE;
    lk_status status = LK_OK;
    bool in_hierarchy_block = false;
    asf_bone_entry *entries = NULL;
    size_t entry_count = 0;
    lk_bone *bones = NULL;
    size_t *order = NULL;
    while (next_line(&cursor)) {
        const char *p = cursor.line_start, *end = cursor.line_end, *token = NULL;
        size_t length = 0, line = cursor.line;
        next_token(&p, end, &token, &length);
        if (*token == ':') {
            in_hierarchy_block = false;
            if (token_is(token, length, ":units"))
                section = UNITS;
            else if (token_is(token, length, ":root"))
                section = ROOT, have_root = true;
            else if (token_is(token, length, ":bonedata"))
                section = BONEDATA;
            else if (token_is(token, length, ":hierarchy"))
                section = HIERARCHY, have_hierarchy = true;
            else
                section = OTHER;
            continue;
        }
        switch (section) {
        case NONE:
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected an ASF section such as ':root'");
            goto done;
        case OTHER: break;
        case UNITS:
            if (token_is(token, length, "angle")) {
                if (!next_token(&p, end, &token, &length) ||
                    !(token_is(token, length, "deg") || token_is(token, length, "rad"))) {
                    status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected 'angle deg' or 'angle rad'");
                    goto done;
                }
                radians = token_is(token, length, "rad");
            } else if (token_is(token, length, "length")) {
                if ((status = read_numbers(&p, end, &length_unit, 1, name, line, "length", error)) != LK_OK) goto done;
            }
            break;
        case ROOT:
            if (token_is(token, length, "order")) {
                root.bone.dof_count = 0;
                while (next_token(&p, end, &token, &length)) {
                    lk_dof dof;
                    if (parse_dof(token, length, &dof) != LK_OK || dof == LK_DOF_L || root.bone.dof_count == 6) {
                        char quoted[32];
                        lk__quote_token(token, end, quoted, sizeof quoted);
                        status = lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                                   "bad root channel '%s' (expected TX TY TZ RX RY RZ)", quoted);
                        goto done;
                    }
                    root.bone.dof[root.bone.dof_count++] = dof;
                }
            } else if (token_is(token, length, "axis")) {
                if (!next_token(&p, end, &token, &length) || !parse_axis_order(token, length, root.bone.axis_order)) {
                    status =
                        lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected a rotation order such as XYZ");
                    goto done;
                }
            } else if (token_is(token, length, "position")) {
                if ((status = read_numbers(&p, end, skeleton->root_position, 3, name, line, "position", error)) !=
                    LK_OK)
                    goto done;
            } else if (token_is(token, length, "orientation")) {
                if ((status = read_numbers(&p, end, root.bone.axis, 3, name, line, "orientation", error)) != LK_OK)
                    goto done;
            }
            break;
        case BONEDATA: {
            if (!token_is(token, length, "begin")) {
                char quoted[32];
                lk__quote_token(token, end, quoted, sizeof quoted);
                status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected 'begin' in :bonedata, got '%s'",
                                           quoted);
                goto done;
            }
            asf_bone_entry entry;
            if ((status = asf_read_bone(&cursor, name, &entry, error)) != LK_OK) goto done;
            if (entries_buffer.size / sizeof entry >= ACCLAIM_MAX_BONES) {
                status = lk__error_at_line(error, LK_ERR_LIMIT, name, line, "more than %u bones", ACCLAIM_MAX_BONES);
                goto done;
            }
            const asf_bone_entry *existing = (const asf_bone_entry *)entries_buffer.data;
            size_t count = entries_buffer.size / sizeof entry;
            if (strcmp(entry.bone.name, "root") == 0 ||
                find_entry(existing, count, entry.bone.name, strlen(entry.bone.name)) >= 0) {
                status =
                    lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' is defined twice", entry.bone.name);
                goto done;
            }
            if (!lk__buffer_append(&entries_buffer, &entry, sizeof entry)) {
                status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
                goto done;
            }
            break;
        }
        case HIERARCHY: {
            if (token_is(token, length, "begin")) {
                in_hierarchy_block = true;
                break;
            }
            if (token_is(token, length, "end")) {
                in_hierarchy_block = false;
                break;
            }
            if (!in_hierarchy_block) {
                status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected 'begin' in :hierarchy");
                goto done;
            }
            asf_bone_entry *list = (asf_bone_entry *)entries_buffer.data;
            size_t count = entries_buffer.size / sizeof *list;
            long parent = token_is(token, length, "root") ? -1 : find_entry(list, count, token, length);
            if (parent == -2) {
                char quoted[32];
                lk__quote_token(token, end, quoted, sizeof quoted);
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line, "unknown bone '%s' in :hierarchy", quoted);
                goto done;
            }
            while (next_token(&p, end, &token, &length)) {
                long child = find_entry(list, count, token, length);
                if (child < 0) {
                    char quoted[32];
                    lk__quote_token(token, end, quoted, sizeof quoted);
                    status =
                        lk__error_at_line(error, LK_ERR_RANGE, name, line, "unknown bone '%s' in :hierarchy", quoted);
                    goto done;
                }
                if (list[child].parent_raw != -2 || child == parent) {
                    status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' is given a second parent",
                                               list[child].bone.name);
                    goto done;
                }
                list[child].parent_raw = parent;
            }
            break;
        }
        }
    }
    entries = (asf_bone_entry *)entries_buffer.data;
    entry_count = entries_buffer.size / sizeof *entries;
    if (!have_root) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no :root section (not an ASF skeleton?)", name);
        goto done;
    }
    if (entry_count && !have_hierarchy) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no :hierarchy section", name);
        goto done;
    }
    for (size_t i = 0; i < entry_count; i++)
        if (entries[i].parent_raw == -2) {
            status = lk__error_at_line(error, LK_ERR_PARSE, name, entries[i].line, "bone '%s' is not in the :hierarchy",
                                       entries[i].bone.name);
            goto done;
        }
    /* Parents first: breadth-first from the root. new_index[i] for entry i. */
    bones = lk__calloc_array(entry_count + 1, sizeof *bones);
    order = lk__malloc_array(entry_count + 1, sizeof *order);
    size_t *new_index = lk__malloc_array(entry_count + 1, sizeof *new_index);
    if (!bones || !order || !new_index) {
        free(new_index);
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
        goto done;
    }
    bones[0] = root.bone;
    bones[0].parent = -1;
    size_t placed = 1;
    order[0] = SIZE_MAX; /* the root */
    for (size_t head = 0; head < placed; head++) {
        long parent_raw = order[head] == SIZE_MAX ? -1 : (long)order[head];
        for (size_t i = 0; i < entry_count; i++)
            if (entries[i].parent_raw == parent_raw) {
                new_index[i] = placed;
                bones[placed] = entries[i].bone;
                bones[placed].parent = (int)head;
                order[placed++] = i;
            }
    }
    free(new_index);
    if (placed != entry_count + 1) {
        for (size_t i = 0; i < entry_count; i++) {
            bool found = false;
            for (size_t k = 1; k < placed && !found; k++) found = order[k] == i;
            if (!found) {
                status = lk__error_at_line(error, LK_ERR_PARSE, name, entries[i].line,
                                           "bone '%s' is on a cycle of the :hierarchy", entries[i].bone.name);
                goto done;
            }
        }
    }
    skeleton->bones = bones;
    bones = NULL;
    skeleton->bone_count = placed;
    skeleton->length_unit = length_unit;
    skeleton->angles_in_radians = radians;
done:
    free(bones);
    free(order);
    lk__buffer_free(&entries_buffer);
    if (status != LK_OK) lk_skeleton_free(skeleton);
    return status;
}

void lk_skeleton_free(lk_skeleton *skeleton)
{
    if (!skeleton) return;
    free(skeleton->bones);
    memset(skeleton, 0, sizeof *skeleton);
}

/* ---- AMC ----------------------------------------------------------------- */

static long skeleton_find(const lk_skeleton *skeleton, const char *token, size_t length)
{
    for (size_t b = 0; b < skeleton->bone_count; b++)
        if (strlen(skeleton->bones[b].name) == length && memcmp(skeleton->bones[b].name, token, length) == 0)
            return (long)b;
    return -1;
}

/* lk_motion_read_memory with the values charged to a memory budget and a
 * frame limit, both enforced while reading (a motion file grows by a frame
 * at a time, so it is stopped as soon as it passes either). The values
 * stay charged. */
static lk_status motion_read_limited(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                     lk__budget *budget, size_t max_frames, lk_motion *motion, lk_error *error);

lk_status lk_motion_read_memory(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                lk_motion *motion, lk_error *error)
{
    lk__budget budget = {(size_t)8 << 30, 0};
    return motion_read_limited(data, size, name, skeleton, &budget, ACCLAIM_MAX_FRAMES, motion, error);
}

static lk_status motion_read_limited(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                     lk__budget *budget, size_t max_frames, lk_motion *motion, lk_error *error)
{
    if (!motion || !skeleton || skeleton->bone_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "lk_motion_read: NULL motion or empty skeleton");
    memset(motion, 0, sizeof *motion);
    if (!name) name = "<memory>";
    if (!data || size == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: empty file", name);
    size_t bone_count = skeleton->bone_count;
    motion->channel_offset = lk__malloc_array(bone_count, sizeof(size_t));
    unsigned char *seen = lk__calloc_array(bone_count, 1);
    double *frame_values = NULL;
    lk__buffer values = {0};
    lk_status status = LK_OK;
    if (!motion->channel_offset || !seen) goto nomem;
    size_t channels = 0;
    for (size_t b = 0; b < bone_count; b++) {
        motion->channel_offset[b] = channels;
        channels += skeleton->bones[b].dof_count;
    }
    motion->channel_count = channels;
    frame_values = lk__malloc_array(channels + 1, sizeof(double));
    if (!frame_values) goto nomem;
    text_cursor cursor = {data, data + size, 0, NULL, NULL};
    double angle_scale = 1; /* AMC unit -> skeleton unit */
    long long frame_number = 0;
    size_t frame_line = 0, frame_count = 0;
    bool in_frame = false;
    /* A frame is complete when every bone with channels appeared once. */
#define FINISH_FRAME()                                                                                                 \
    do {                                                                                                               \
        for (size_t b = 0; b < bone_count; b++)                                                                        \
            if (skeleton->bones[b].dof_count && !seen[b]) {                                                            \
                status = lk__error_at_line(error, LK_ERR_PARSE, name, frame_line, "frame %lld lacks bone '%s'",        \
                                           frame_number, skeleton->bones[b].name);                                     \
                goto done;                                                                                             \
            }                                                                                                          \
        if (frame_count >= max_frames) {                                                                               \
            status = lk__error_at_line(error, LK_ERR_LIMIT, name, frame_line, "more than %zu frames", max_frames);     \
            goto done;                                                                                                 \
        }                                                                                                              \
        lk_status grown = lk__buffer_append_charged(&values, frame_values, channels * sizeof(double), budget);         \
        if (grown == LK_ERR_LIMIT) {                                                                                   \
            status = lk__error_at_line(error, LK_ERR_LIMIT, name, frame_line,                                          \
                                       "%zu frames of %zu channels need more than the memory budget of %zu bytes",     \
                                       frame_count + 1, channels, budget->limit);                                      \
            goto done;                                                                                                 \
        }                                                                                                              \
        if (grown != LK_OK) goto nomem;                                                                                \
        frame_count++;                                                                                                 \
    } while (0)
    while (next_line(&cursor)) {
        const char *p = cursor.line_start, *end = cursor.line_end, *token = NULL;
        size_t length = 0, line = cursor.line;
        if (*p == ':') {
            next_token(&p, end, &token, &length);
            if (token_is(token, length, ":DEGREES"))
                angle_scale = skeleton->angles_in_radians ? 0.017453292519943295769 : 1;
            else if (token_is(token, length, ":RADIANS"))
                angle_scale = skeleton->angles_in_radians ? 1 : 57.295779513082320877;
            continue;
        }
        long long number;
        const char *q = p;
        if (lk__parse_int64(&q, end, &number) && lk__skip_spaces(q, end) == end) {
            if (in_frame) FINISH_FRAME();
            if (in_frame && number != frame_number + 1) {
                status = lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                           "frame %lld follows frame %lld (missing or repeated frames)", number,
                                           frame_number);
                goto done;
            }
            frame_number = number;
            frame_line = line;
            in_frame = true;
            memset(seen, 0, bone_count);
            continue;
        }
        next_token(&p, end, &token, &length);
        if (!in_frame) {
            char quoted[32];
            lk__quote_token(token, end, quoted, sizeof quoted);
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "'%s' before the first frame number", quoted);
            goto done;
        }
        long bone = skeleton_find(skeleton, token, length);
        if (bone < 0) {
            char quoted[32];
            lk__quote_token(token, end, quoted, sizeof quoted);
            status =
                lk__error_at_line(error, LK_ERR_RANGE, name, line, "unknown bone '%s' (not in the skeleton)", quoted);
            goto done;
        }
        if (seen[bone]) {
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' appears twice in frame %lld",
                                       skeleton->bones[bone].name, frame_number);
            goto done;
        }
        seen[bone] = 1;
        const lk_bone *b = &skeleton->bones[bone];
        double *out = frame_values + motion->channel_offset[bone];
        for (unsigned k = 0; k < b->dof_count; k++) {
            if (!lk__parse_double(&p, end, &out[k])) {
                status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' needs %u values, got %u",
                                           b->name, b->dof_count, k);
                goto done;
            }
            if (!isfinite(out[k])) {
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line, "bone '%s' value %u is not finite", b->name,
                                           k + 1);
                goto done;
            }
            if (b->dof[k] >= LK_DOF_RX && b->dof[k] <= LK_DOF_RZ) out[k] *= angle_scale;
        }
        if (lk__skip_spaces(p, end) != end) {
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "bone '%s' has more than %u values", b->name,
                                       b->dof_count);
            goto done;
        }
    }
    if (!in_frame) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no frames (expected a frame number line)", name);
        goto done;
    }
    FINISH_FRAME();
#undef FINISH_FRAME
    motion->frame_count = frame_count;
    motion->values = lk__buffer_take_charged(&values, budget);
    if (!motion->values) motion->values = lk__malloc_array(1, sizeof(double));
    if (!motion->values) goto nomem;
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
done:
    free(seen);
    free(frame_values);
    lk__buffer_free_charged(&values, budget);
    if (status != LK_OK) lk_motion_free(motion);
    return status;
}

void lk_motion_free(lk_motion *motion)
{
    if (!motion) return;
    free(motion->channel_offset);
    free(motion->values);
    memset(motion, 0, sizeof *motion);
}

/* ---- WGT ----------------------------------------------------------------- */

typedef struct wgt_entry {
    uint32_t vertex, bone;
    float weight;
} wgt_entry;

/* lk_bone_weights_read_memory with everything charged to a memory budget
 * (a pair is 4 bytes of text, 12 while reading and 8 in the result, which
 * stays charged). */
static lk_status weights_read_limited(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                      size_t vertex_count, lk__budget *budget, lk_bone_weights *weights,
                                      lk_error *error);

lk_status lk_bone_weights_read_memory(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                      size_t vertex_count, lk_bone_weights *weights, lk_error *error)
{
    lk__budget budget = {(size_t)8 << 30, 0};
    return weights_read_limited(data, size, name, skeleton, vertex_count, &budget, weights, error);
}

static lk_status weights_over_budget(const char *name, size_t line, const lk__budget *budget, lk_error *error)
{
    if (line)
        return lk__error_at_line(error, LK_ERR_LIMIT, name, line,
                                 "the bone weights need more than the memory budget of %zu bytes", budget->limit);
    return lk_error_set(error, LK_ERR_LIMIT, "%s: the bone weights need more than the memory budget of %zu bytes", name,
                        budget->limit);
}

static lk_status weights_read_limited(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                      size_t vertex_count, lk__budget *budget, lk_bone_weights *weights,
                                      lk_error *error)
{
    if (!weights || !skeleton) return lk_error_set(error, LK_ERR_INVALID, "lk_bone_weights_read: NULL argument");
    memset(weights, 0, sizeof *weights);
    if (!name) name = "<memory>";
    if (!data || size == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: empty file", name);
    if (vertex_count > UINT32_MAX - 1) return lk_error_set(error, LK_ERR_LIMIT, "%s: too many vertices", name);
    text_cursor cursor = {data, data + size, 0, NULL, NULL};
    lk__buffer entries = {0};
    if (!lk__budget_charge(budget, vertex_count + 1, sizeof(uint32_t)))
        return weights_over_budget(name, 0, budget, error);
    uint32_t *line_of_vertex = lk__calloc_array(vertex_count + 1, sizeof(uint32_t));
    lk_status status = LK_OK;
    if (!line_of_vertex) goto nomem;
    if (!next_line(&cursor)) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: empty file", name);
        goto done;
    }
    {
        const char *p = cursor.line_start, *end = cursor.line_end, *token = NULL;
        size_t length = 0;
        double version;
        next_token(&p, end, &token, &length);
        if (!token_is(token, length, "wgt") || !lk__parse_double(&p, end, &version) || lk__skip_spaces(p, end) != end) {
            status = lk__error_at_line(error, LK_ERR_PARSE, name, cursor.line, "not a WGT file (expected 'wgt 1')");
            goto done;
        }
        if (version != 1) {
            status = lk__error_at_line(error, LK_ERR_UNSUPPORTED, name, cursor.line, "WGT version %g (only 1 exists)",
                                       version);
            goto done;
        }
    }
    while (next_line(&cursor)) {
        const char *p = cursor.line_start, *end = cursor.line_end, *token = NULL;
        size_t length = 0, line = cursor.line;
        long long vertex;
        if (!lk__parse_int64(&p, end, &vertex) || (p < end && !lk__is_space(*p))) {
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected a vertex number (1-based) first");
            goto done;
        }
        if (vertex < 1 || (unsigned long long)vertex > vertex_count) {
            status = lk__error_at_line(error, LK_ERR_RANGE, name, line, "vertex %lld out of range (the mesh has %zu)",
                                       vertex, vertex_count);
            goto done;
        }
        if (line_of_vertex[vertex]) {
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "vertex %lld already listed at line %u", vertex,
                                       line_of_vertex[vertex]);
            goto done;
        }
        line_of_vertex[vertex] = line > UINT32_MAX ? UINT32_MAX : (uint32_t)line;
        size_t pairs = 0;
        while (next_token(&p, end, &token, &length)) {
            long bone = skeleton_find(skeleton, token, length);
            if (bone < 0) {
                char quoted[32];
                lk__quote_token(token, end, quoted, sizeof quoted);
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line, "unknown bone '%s' (not in the skeleton)",
                                           quoted);
                goto done;
            }
            double weight;
            if (!lk__parse_double(&p, end, &weight)) {
                status = lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected a weight after bone '%s'",
                                           skeleton->bones[bone].name);
                goto done;
            }
            if (!isfinite(weight) || weight < 0) {
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line,
                                           "weight %g of bone '%s' is not a finite "
                                           "non-negative number",
                                           weight, skeleton->bones[bone].name);
                goto done;
            }
            wgt_entry entry = {(uint32_t)(vertex - 1), (uint32_t)bone, (float)weight};
            if (entries.size / sizeof entry >= UINT32_MAX - 1) goto nomem;
            lk_status grown = lk__buffer_append_charged(&entries, &entry, sizeof entry, budget);
            if (grown == LK_ERR_LIMIT) {
                status = weights_over_budget(name, line, budget, error);
                goto done;
            }
            if (grown != LK_OK) goto nomem;
            pairs++;
        }
        if (pairs == 0) {
            status =
                lk__error_at_line(error, LK_ERR_PARSE, name, line, "vertex %lld has no 'bone weight' pair", vertex);
            goto done;
        }
    }
    {
        size_t count = entries.size / sizeof(wgt_entry);
        const wgt_entry *list = (const wgt_entry *)entries.data;
        /* The result (kept charged) and the fill cursors. */
        if (!lk__budget_charge(budget, count + 1, sizeof(uint32_t) + sizeof(float)) ||
            !lk__budget_charge(budget, vertex_count + 1, 2 * sizeof(uint32_t))) {
            status = weights_over_budget(name, 0, budget, error);
            goto done;
        }
        weights->vertex_count = vertex_count;
        weights->offsets = lk__calloc_array(vertex_count + 1, sizeof(uint32_t));
        weights->bones = lk__malloc_array(count + 1, sizeof(uint32_t));
        weights->weights = lk__malloc_array(count + 1, sizeof(float));
        uint32_t *fill = lk__malloc_array(vertex_count + 1, sizeof(uint32_t));
        if (!weights->offsets || !weights->bones || !weights->weights || !fill) {
            free(fill);
            goto nomem;
        }
        /* Counting sort by vertex, keeping the file's order within one. */
        for (size_t i = 0; i < count; i++) weights->offsets[list[i].vertex + 1]++;
        for (size_t v = 0; v < vertex_count; v++) weights->offsets[v + 1] += weights->offsets[v];
        memcpy(fill, weights->offsets, (vertex_count + 1) * sizeof(uint32_t));
        for (size_t i = 0; i < count; i++) {
            uint32_t at = fill[list[i].vertex]++;
            weights->bones[at] = list[i].bone;
            weights->weights[at] = list[i].weight;
        }
        free(fill);
        lk__budget_release(budget, vertex_count + 1, sizeof(uint32_t));
    }
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
done:
    free(line_of_vertex);
    lk__budget_release(budget, vertex_count + 1, sizeof(uint32_t));
    lk__buffer_free_charged(&entries, budget);
    if (status != LK_OK) lk_bone_weights_free(weights);
    return status;
}

void lk_bone_weights_free(lk_bone_weights *weights)
{
    if (!weights) return;
    free(weights->offsets);
    free(weights->bones);
    free(weights->weights);
    memset(weights, 0, sizeof *weights);
}

/* ---- files --------------------------------------------------------------- */

lk_status lk_skeleton_read(const char *path, lk_skeleton *skeleton, lk_error *error)
{
    if (skeleton) memset(skeleton, 0, sizeof *skeleton);
    char *data;
    size_t size;
    lk_status status = lk__read_file(path, 0, &data, &size, error);
    if (status != LK_OK) return status;
    status = lk_skeleton_read_memory(data, size, path, skeleton, error);
    free(data);
    return status;
}

lk_status lk_motion_read(const char *path, const lk_skeleton *skeleton, lk_motion *motion, lk_error *error)
{
    if (motion) memset(motion, 0, sizeof *motion);
    char *data;
    size_t size;
    lk_status status = lk__read_file(path, 0, &data, &size, error);
    if (status != LK_OK) return status;
    status = lk_motion_read_memory(data, size, path, skeleton, motion, error);
    free(data);
    return status;
}

lk_status lk_bone_weights_read(const char *path, const lk_skeleton *skeleton, size_t vertex_count,
                               lk_bone_weights *weights, lk_error *error)
{
    if (weights) memset(weights, 0, sizeof *weights);
    char *data;
    size_t size;
    lk_status status = lk__read_file(path, 0, &data, &size, error);
    if (status != LK_OK) return status;
    status = lk_bone_weights_read_memory(data, size, path, skeleton, vertex_count, weights, error);
    free(data);
    return status;
}

/* The four files of an Acclaim set share one budget: each file is held
 * while it is parsed, and the mesh, the motion and the weights stay held
 * (charged) until the frames are made from them. */
lk_status lk_animation_read_acclaim(const char *smf_path, const char *asf_path, const char *amc_path,
                                    const char *wgt_path, const lk_animation_read_options *options,
                                    lk_animation *animation, lk_animation_report *report, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "NULL animation");
    lk_animation_init(animation);
    if (!smf_path || !asf_path || !amc_path || !wgt_path)
        return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read_acclaim: NULL path");
    lk__budget budget = {options && options->max_bytes ? options->max_bytes : (size_t)8 << 30, 0};
    lk_mesh mesh;
    lk_skeleton skeleton;
    lk_motion motion;
    lk_bone_weights weights;
    memset(&skeleton, 0, sizeof skeleton);
    memset(&motion, 0, sizeof motion);
    memset(&weights, 0, sizeof weights);
    size_t max_frames = options && options->max_frames ? options->max_frames : LK__ANIM_DEFAULT_MAX_FRAMES;
    char *data = NULL;
    size_t size = 0;
    lk_status status = lk__mesh_read_charged(smf_path, LK_FORMAT_AUTO, &budget, &mesh, error);
    /* The skeleton has at most ACCLAIM_MAX_BONES bones: not charged. */
    if (status == LK_OK) status = lk__read_file_charged(asf_path, &budget, &data, &size, error);
    if (status == LK_OK) status = lk_skeleton_read_memory(data, size, asf_path, &skeleton, error);
    free(data);
    lk__budget_release(&budget, size, 1);
    data = NULL;
    size = 0;
    if (status == LK_OK) status = lk__read_file_charged(amc_path, &budget, &data, &size, error);
    if (status == LK_OK)
        status = motion_read_limited(data, size, amc_path, &skeleton, &budget,
                                     max_frames < ACCLAIM_MAX_FRAMES ? max_frames : ACCLAIM_MAX_FRAMES, &motion, error);
    free(data);
    lk__budget_release(&budget, size, 1);
    data = NULL;
    size = 0;
    if (status == LK_OK) status = lk__read_file_charged(wgt_path, &budget, &data, &size, error);
    if (status == LK_OK)
        status = weights_read_limited(data, size, wgt_path, &skeleton, mesh.vertex_count, &budget, &weights, error);
    free(data);
    lk__budget_release(&budget, size, 1);
    /* The skinned frames: refused here, naming the motion, rather than by
     * lk__animation_from_acclaim. */
    if (status == LK_OK && mesh.vertex_count &&
        motion.frame_count > lk__budget_room(&budget) / (3 * sizeof(float)) / mesh.vertex_count)
        status = lk_error_set(error, LK_ERR_LIMIT,
                              "%s: %zu frames of %zu vertices would need more than the memory budget of %zu bytes",
                              amc_path, motion.frame_count, mesh.vertex_count, budget.limit);
    if (status == LK_OK) {
        lk_error inner = {0};
        status =
            lk__animation_from_acclaim(&mesh, &skeleton, &motion, &weights, options ? options->frames_per_second : 0,
                                       &budget, animation, report, &inner);
        if (status != LK_OK) lk_error_set(error, status, "%s: %s", amc_path, inner.message);
    }
    lk_mesh_free(&mesh);
    lk_skeleton_free(&skeleton);
    lk_motion_free(&motion);
    lk_bone_weights_free(&weights);
    return status;
}
