/* Animated meshes: the lk_animation container, format dispatch for reading
 * and writing animations, Acclaim forward kinematics and linear-blend
 * skinning. The formats themselves live in io_md2.c, io_kmf.c, io_gltf.c and
 * io_acclaim.c. */
#include "anim_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LK_ANIM_DEFAULT_MAX_BYTES ((size_t)8 << 30)
#define LK_DEG_TO_RAD 0.017453292519943295769

void lk_animation_init(lk_animation *animation) { memset(animation, 0, sizeof *animation); }

void lk_animation_free(lk_animation *animation)
{
    if (!animation) return;
    lk_mesh_free(&animation->mesh);
    free(animation->frame_positions);
    if (animation->frame_names) {
        for (size_t f = 0; f < animation->frame_count; f++) free(animation->frame_names[f]);
        free(animation->frame_names);
    }
    lk_animation_init(animation);
}

lk_status lk_animation_frame(const lk_animation *animation, size_t frame, lk_mesh *out, lk_error *error)
{
    if (!animation || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_frame: NULL argument");
    if (frame >= animation->frame_count)
        return lk_error_set(error, LK_ERR_RANGE, "frame %zu does not exist (the animation has %zu frames)", frame,
                            animation->frame_count);
    if (!animation->frame_positions)
        return lk_error_set(error, LK_ERR_INVALID, "animation has no frame positions");
    lk_mesh copy;
    lk_status status = lk_mesh_copy(&copy, &animation->mesh, error);
    if (status != LK_OK) return status;
    size_t floats = animation->mesh.vertex_count * 3;
    if (floats) memcpy(copy.positions, animation->frame_positions + frame * floats, floats * sizeof(float));
    *out = copy;
    return LK_OK;
}

lk_status lk__animation_alloc_frames(lk_animation *animation, size_t frame_count, lk__budget *budget,
                                     const char *what, lk_error *error)
{
    size_t floats_per_frame = animation->mesh.vertex_count * 3;
    if (frame_count == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: no frames", what);
    if (floats_per_frame && (frame_count > lk__budget_room(budget) / sizeof(float) / floats_per_frame ||
                             !lk__budget_charge(budget, frame_count, floats_per_frame * sizeof(float))))
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: %zu frames of %zu vertices would need more than the memory budget of %zu bytes",
                            what, frame_count, animation->mesh.vertex_count, budget->limit);
    animation->frame_positions = lk__malloc_array(frame_count, floats_per_frame * sizeof(float));
    if (!animation->frame_positions)
        return lk_error_set(error, LK_ERR_NOMEM, "%s: cannot allocate %zu frames of %zu vertices", what,
                            frame_count, animation->mesh.vertex_count);
    animation->frame_count = frame_count;
    return LK_OK;
}

lk_status lk__animation_take_frame0(lk_animation *animation, lk_mesh *mesh, lk_error *error)
{
    (void)error;
    /* mesh.positions already hold frame 0 by contract. */
    *mesh = animation->mesh;
    lk_mesh_init(&animation->mesh);
    lk_animation_free(animation);
    return LK_OK;
}

lk_status lk_animation_validate(const lk_animation *animation, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "NULL animation");
    if (animation->frame_count < 1 || !animation->frame_positions)
        return lk_error_set(error, LK_ERR_INVALID, "animation has no frames");
    if (!(animation->frames_per_second > 0) || !isfinite(animation->frames_per_second))
        return lk_error_set(error, LK_ERR_INVALID, "frames_per_second %g is not a positive number",
                            animation->frames_per_second);
    lk_error inner = {0};
    lk_status status = lk_mesh_validate(&animation->mesh, &inner);
    if (status != LK_OK) return lk_error_set(error, status, "frame 0 mesh: %s", inner.message);
    size_t floats = animation->mesh.vertex_count * 3;
    for (size_t f = 0; f < animation->frame_count; f++) {
        const float *p = animation->frame_positions + f * floats;
        for (size_t i = 0; i < floats; i++)
            if (!isfinite(p[i]))
                return lk_error_set(error, LK_ERR_RANGE, "frame %zu: vertex %zu has a non-finite coordinate", f,
                                    i / 3);
    }
    return LK_OK;
}

/* ---- reading and writing ---------------------------------------------- */

typedef enum anim_format { ANIM_UNKNOWN, ANIM_KMF, ANIM_MD2, ANIM_GLTF, ANIM_ACCLAIM } anim_format;

static anim_format anim_format_from_path(const char *path, const char **extension)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    *extension = dot ? dot : base + strlen(base);
    if (!dot) return ANIM_UNKNOWN;
    size_t len = strlen(dot + 1);
    if (lk__word_equals(dot + 1, len, "kmf")) return ANIM_KMF;
    if (lk__word_equals(dot + 1, len, "md2")) return ANIM_MD2;
    if (lk__word_equals(dot + 1, len, "gltf") || lk__word_equals(dot + 1, len, "glb")) return ANIM_GLTF;
    if (lk__word_equals(dot + 1, len, "amc") || lk__word_equals(dot + 1, len, "asf")) return ANIM_ACCLAIM;
    return ANIM_UNKNOWN;
}

static char *directory_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    size_t length = slash ? (size_t)(slash - path) : 1;
    char *directory = malloc(length + 2);
    if (!directory) return NULL;
    if (!slash) strcpy(directory, ".");
    else if (slash == path) strcpy(directory, "/");
    else {
        memcpy(directory, path, length);
        directory[length] = '\0';
    }
    return directory;
}

/* path with its extension (starting at `extension`) replaced by `new_ext`. */
static char *with_extension(const char *path, const char *extension, const char *new_ext)
{
    size_t stem = (size_t)(extension - path);
    char *out = malloc(stem + strlen(new_ext) + 1);
    if (!out) return NULL;
    memcpy(out, path, stem);
    strcpy(out + stem, new_ext);
    return out;
}

lk_status lk_animation_read(const char *path, lk_animation *animation, lk_error *error)
{
    return lk_animation_read_ex(path, NULL, animation, NULL, error);
}

static size_t anim_limit(const lk_animation_read_options *options)
{
    return options && options->max_bytes ? options->max_bytes : LK_ANIM_DEFAULT_MAX_BYTES;
}

static void fill_context(lk__anim_context *ctx, const char *name, const char *directory, lk__budget *budget,
                         const lk_animation_read_options *options, lk_animation_report *report)
{
    ctx->name = name;
    ctx->directory = directory;
    ctx->budget = budget;
    ctx->max_frames = options && options->max_frames ? options->max_frames : LK__ANIM_DEFAULT_MAX_FRAMES;
    ctx->frames_per_second = options ? options->frames_per_second : 0;
    ctx->animation_index = options ? options->animation_index : 0;
    ctx->all_animations = options ? options->all_animations : 0;
    ctx->report = report;
}

/* Reads one file already in memory; validates the result. */
static lk_status read_data(const char *data, size_t size, anim_format format, const lk__anim_context *ctx,
                           lk_animation *animation, lk_error *error)
{
    lk_status status;
    if (size == 0) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: empty file", ctx->name);
    } else if (ctx->frames_per_second < 0 || !isfinite(ctx->frames_per_second)) {
        status = lk_error_set(error, LK_ERR_INVALID, "frames_per_second %g must be >= 0", ctx->frames_per_second);
    } else {
        switch (format) {
        case ANIM_KMF: status = lk__anim_read_kmf(data, size, ctx, animation, error); break;
        case ANIM_MD2: status = lk__anim_read_md2((const unsigned char *)data, size, ctx, animation, error); break;
        case ANIM_GLTF: status = lk__anim_read_gltf(data, size, ctx, animation, error); break;
        default:
            status = lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: an Acclaim set cannot be read from memory", ctx->name);
            break;
        }
    }
    if (status == LK_OK) {
        lk_error inner = {0};
        status = lk_animation_validate(animation, &inner);
        if (status != LK_OK) status = lk_error_set(error, status, "%s: %s", ctx->name, inner.message);
    }
    if (status != LK_OK) lk_animation_free(animation);
    return status;
}

lk_status lk_animation_read_memory(const void *data, size_t size, const char *name,
                                   const lk_animation_read_options *options, lk_animation *animation,
                                   lk_animation_report *report, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read_memory: NULL animation");
    lk_animation_init(animation);
    if (!name) name = "<memory>";
    lk_animation_report local_report;
    if (!report) report = &local_report;
    memset(report, 0, sizeof *report);
    const char *extension;
    anim_format format = anim_format_from_path(name, &extension);
    if (format == ANIM_UNKNOWN)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: not an animation file name (expected .kmf, .md2, .gltf or .glb)", name);
    /* The caller's bytes are held while they are parsed, as a file's are. */
    lk__budget budget = {anim_limit(options), 0};
    if (!lk__budget_charge(&budget, size, 1)) return lk__input_too_large(name, size, &budget, error);
    lk__anim_context ctx;
    fill_context(&ctx, name, NULL, &budget, options, report);
    return read_data(data, size, format, &ctx, animation, error);
}

lk_status lk_animation_read_ex(const char *path, const lk_animation_read_options *options,
                               lk_animation *animation, lk_animation_report *report, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read: NULL animation");
    lk_animation_init(animation);
    if (!path) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read: NULL path");
    lk_animation_report local_report;
    if (!report) report = &local_report;
    memset(report, 0, sizeof *report);
    const char *extension;
    anim_format format = anim_format_from_path(path, &extension);
    if (format == ANIM_UNKNOWN)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: not an animation file (expected .kmf, .md2, .gltf, .glb, .amc or .asf)", path);
    if (format == ANIM_ACCLAIM) {
        /* The set is named by its stem: X.asf, X.amc, X.smf, X.wgt. */
        char *asf = with_extension(path, extension, ".asf");
        char *amc = with_extension(path, extension, ".amc");
        char *smf = with_extension(path, extension, ".smf");
        char *wgt = with_extension(path, extension, ".wgt");
        lk_status status;
        if (!asf || !amc || !smf || !wgt)
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        else
            status = lk_animation_read_acclaim(smf, asf, amc, wgt, options, animation, report, error);
        free(asf);
        free(amc);
        free(smf);
        free(wgt);
        return status;
    }
    char *data;
    size_t size;
    /* The file is held whole while it is parsed: it counts against the
     * budget, and one larger than it is refused before it is read. */
    lk__budget budget = {anim_limit(options), 0};
    lk_status status = lk__read_file_charged(path, &budget, &data, &size, error);
    if (status != LK_OK) return status;
    char *directory = directory_of(path);
    if (!directory) {
        free(data);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    lk__anim_context ctx;
    fill_context(&ctx, path, directory, &budget, options, report);
    status = read_data(data, size, format, &ctx, animation, error);
    free(directory);
    free(data);
    return status;
}

lk_status lk_animation_write(const char *path, const lk_animation *animation, lk_error *error)
{
    if (!path || !animation) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_write: NULL argument");
    const char *extension;
    anim_format format = anim_format_from_path(path, &extension);
    lk_status (*writer)(FILE *, const lk_animation *, const char *, lk_error *) = NULL;
    switch (format) {
    case ANIM_KMF: writer = lk__anim_write_kmf; break;
    case ANIM_MD2: writer = lk__anim_write_md2; break;
    case ANIM_GLTF:
        if (lk__word_equals(extension + 1, strlen(extension + 1), "glb"))
            return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: writing .glb is not supported (use .gltf)", path);
        writer = lk__anim_write_gltf;
        break;
    default:
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: cannot write an animation in this format (use .kmf, .md2 or .gltf)", path);
    }
    lk_error inner = {0};
    lk_status status = lk_animation_validate(animation, &inner);
    if (status != LK_OK)
        return lk_error_set(error, status, "%s: refusing to write an invalid animation: %s", path, inner.message);
    lk__atomic_file out;
    status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    status = writer(out.file, animation, path, error);
    if (status != LK_OK) return lk__atomic_fail(&out, error);
    return lk__atomic_commit(&out, error);
}

/* ---- Acclaim forward kinematics ---------------------------------------- */

/* 4x4 column-major matrices acting on column vectors: m[col * 4 + row]. */
static void mat_identity(double m[16])
{
    memset(m, 0, 16 * sizeof(double));
    m[0] = m[5] = m[10] = m[15] = 1;
}

static void mat_mul(const double a[16], const double b[16], double out[16])
{
    double r[16];
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[k * 4 + row] * b[c * 4 + k];
            r[c * 4 + row] = s;
        }
    memcpy(out, r, sizeof r);
}

static void mat_rotation(int axis, double radians, double m[16])
{
    mat_identity(m);
    double c = cos(radians), s = sin(radians);
    int i = (axis + 1) % 3, j = (axis + 2) % 3;
    /* Rotation in the (i, j) plane, right-handed about `axis`. */
    m[i * 4 + i] = c;
    m[j * 4 + i] = -s;
    m[i * 4 + j] = s;
    m[j * 4 + j] = c;
}

/* Rotation for angles (one per axis X, Y, Z) applied in `order` ("XYZ" = X
 * first, then Y, then Z; as column vectors R = Rz * Ry * Rx). */
static void euler_matrix(const double angles[3], const char order[4], double to_radians, double m[16])
{
    mat_identity(m);
    for (int k = 0; k < 3 && order[k]; k++) {
        int axis = order[k] - 'X';
        if (axis < 0 || axis > 2) continue;
        double r[16];
        mat_rotation(axis, angles[axis] * to_radians, r);
        mat_mul(r, m, m);
    }
}

static void mat_transpose3(const double a[16], double out[16])
{
    /* Rotation-only inverse. */
    mat_identity(out);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) out[c * 4 + r] = a[r * 4 + c];
}

lk_status lk_skeleton_pose(const lk_skeleton *skeleton, const lk_motion *motion, size_t frame, double *out,
                           lk_error *error)
{
    if (!skeleton || !out || skeleton->bone_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "lk_skeleton_pose: empty skeleton");
    if (frame != SIZE_MAX && (!motion || frame >= motion->frame_count))
        return lk_error_set(error, LK_ERR_RANGE, "motion has no frame %zu", frame);
    double to_radians = skeleton->angles_in_radians ? 1.0 : LK_DEG_TO_RAD;
    /* Bone start points in world space, from the base pose walk. */
    for (size_t b = 0; b < skeleton->bone_count; b++) {
        const lk_bone *bone = &skeleton->bones[b];
        const double *values = frame == SIZE_MAX ? NULL
                                                 : motion->values + frame * motion->channel_count +
                                                       motion->channel_offset[b];
        double rotation_angles[3] = {0, 0, 0}, translation[3] = {0, 0, 0};
        char order[4] = {0};
        int rotations = 0;
        for (unsigned k = 0; k < bone->dof_count; k++) {
            double value = values ? values[k] : 0;
            if (!isfinite(value))
                return lk_error_set(error, LK_ERR_RANGE, "frame %zu: bone '%s' channel %u is not finite", frame + 1,
                                    bone->name, k + 1);
            lk_dof dof = bone->dof[k];
            if (dof <= LK_DOF_TZ) translation[dof] = value;
            else if (dof <= LK_DOF_RZ) {
                rotation_angles[dof - LK_DOF_RX] = value;
                if (rotations < 3) order[rotations++] = (char)('X' + (dof - LK_DOF_RX));
            }
        }
        /* C: the bone's local axes; M: the motion in those axes; the world
         * rotation composes parent * C * M * C^-1 (the Acclaim convention). */
        double c[16], c_inverse[16], m[16], local[16];
        euler_matrix(bone->axis, bone->axis_order, to_radians, c);
        mat_transpose3(c, c_inverse);
        euler_matrix(rotation_angles, order, to_radians, m);
        mat_mul(c, m, local);
        mat_mul(local, c_inverse, local);
        double *world = out + 16 * b;
        if (bone->parent < 0) {
            memcpy(world, local, sizeof local);
            for (int k = 0; k < 3; k++) world[12 + k] = skeleton->root_position[k] + translation[k];
        } else {
            const double *parent = out + 16 * (size_t)bone->parent;
            const lk_bone *parent_bone = &skeleton->bones[bone->parent];
            mat_mul(parent, local, world);
            /* Start = parent's start + parent's world rotation applied to the
             * parent's base-pose vector. */
            double offset[3];
            for (int k = 0; k < 3; k++) offset[k] = parent_bone->direction[k] * parent_bone->length;
            for (int r = 0; r < 3; r++)
                world[12 + r] = parent[12 + r] + parent[0 * 4 + r] * offset[0] + parent[1 * 4 + r] * offset[1] +
                                parent[2 * 4 + r] * offset[2];
        }
        world[3] = world[7] = world[11] = 0;
        world[15] = 1;
    }
    return LK_OK;
}

lk_status lk_animation_from_acclaim(const lk_mesh *rest_pose, const lk_skeleton *skeleton,
                                    const lk_motion *motion, const lk_bone_weights *weights,
                                    double frames_per_second, lk_animation *out,
                                    lk_animation_report *report, lk_error *error)
{
    lk__budget budget = {LK_ANIM_DEFAULT_MAX_BYTES, 0};
    return lk__animation_from_acclaim(rest_pose, skeleton, motion, weights, frames_per_second, &budget, out, report,
                                      error);
}

lk_status lk__animation_from_acclaim(const lk_mesh *rest_pose, const lk_skeleton *skeleton, const lk_motion *motion,
                                     const lk_bone_weights *weights, double frames_per_second, lk__budget *budget,
                                     lk_animation *out, lk_animation_report *report, lk_error *error)
{
    lk_animation_report local_report;
    if (!report) report = &local_report;
    memset(report, 0, sizeof *report);
    if (!rest_pose || !skeleton || !motion || !weights || !out)
        return lk_error_set(error, LK_ERR_INVALID, "lk_animation_from_acclaim: NULL argument");
    lk_animation_init(out);
    if (weights->vertex_count != rest_pose->vertex_count)
        return lk_error_set(error, LK_ERR_RANGE, "weights are for %zu vertices but the mesh has %zu",
                            weights->vertex_count, rest_pose->vertex_count);
    if (motion->frame_count == 0) return lk_error_set(error, LK_ERR_PARSE, "motion has no frames");
    if (frames_per_second <= 0 || !isfinite(frames_per_second)) frames_per_second = 120;
    size_t bone_count = skeleton->bone_count;
    report->bone_count = bone_count;
    report->key_count = motion->frame_count;
    report->skinned = 1;
    /* Charged with the copy of the rest pose; the frames come next. */
    size_t pair_count = weights->offsets[weights->vertex_count];
    unsigned attributes = (rest_pose->normals ? LK_ATTR_NORMALS : 0u) | (rest_pose->texcoords ? LK_ATTR_TEXCOORDS : 0u) |
                          (rest_pose->colors ? LK_ATTR_COLORS : 0u) | (rest_pose->radii ? LK_ATTR_RADII : 0u);
    if (!lk__budget_charge(budget, pair_count + 1, sizeof(float)) ||
        !lk__budget_charge_mesh(budget, rest_pose->vertex_count, rest_pose->triangle_count, attributes))
        return lk_error_set(error, LK_ERR_LIMIT, "%zu vertices with %zu bone weights need more than the memory budget "
                            "of %zu bytes", rest_pose->vertex_count, pair_count, budget->limit);
    double *base = lk__malloc_array(bone_count, 16 * sizeof(double));
    double *pose = lk__malloc_array(bone_count, 16 * sizeof(double));
    double *skin = lk__malloc_array(bone_count, 16 * sizeof(double));
    float *normalised = lk__malloc_array(pair_count + 1, sizeof(float));
    lk_status status = LK_OK;
    if (!base || !pose || !skin || !normalised) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu bones", bone_count);
        goto done;
    }
    /* Normalise weights once. */
    for (size_t v = 0; v < weights->vertex_count; v++) {
        double sum = 0;
        for (uint32_t k = weights->offsets[v]; k < weights->offsets[v + 1]; k++) sum += weights->weights[k];
        if (weights->offsets[v] == weights->offsets[v + 1] || !(sum > 0)) {
            report->vertices_unweighted++;
            continue;
        }
        if (fabs(sum - 1) > 1e-3) report->weights_normalised++;
        for (uint32_t k = weights->offsets[v]; k < weights->offsets[v + 1]; k++)
            normalised[k] = (float)(weights->weights[k] / sum);
    }
    status = lk_mesh_copy(&out->mesh, rest_pose, error);
    if (status != LK_OK) goto done;
    status = lk__animation_alloc_frames(out, motion->frame_count, budget, "acclaim", error);
    if (status != LK_OK) goto done;
    out->frames_per_second = frames_per_second;
    status = lk_skeleton_pose(skeleton, NULL, SIZE_MAX, base, error);
    if (status != LK_OK) goto done;
    for (size_t b = 0; b < bone_count; b++) {
        /* Base pose inverse: rotation transpose, translation -R^T t. */
        double *m = base + 16 * b, inverse[16];
        mat_transpose3(m, inverse);
        for (int r = 0; r < 3; r++)
            inverse[12 + r] = -(inverse[0 * 4 + r] * m[12] + inverse[1 * 4 + r] * m[13] + inverse[2 * 4 + r] * m[14]);
        memcpy(m, inverse, sizeof inverse);
    }
    size_t vertex_count = rest_pose->vertex_count;
    for (size_t f = 0; f < motion->frame_count; f++) {
        status = lk_skeleton_pose(skeleton, motion, f, pose, error);
        if (status != LK_OK) goto done;
        for (size_t b = 0; b < bone_count; b++) mat_mul(pose + 16 * b, base + 16 * b, skin + 16 * b);
        float *frame = out->frame_positions + f * vertex_count * 3;
        for (size_t v = 0; v < vertex_count; v++) {
            const float *p = rest_pose->positions + 3 * v;
            double acc[3] = {0, 0, 0};
            uint32_t begin = weights->offsets[v], end = weights->offsets[v + 1];
            double sum = 0;
            for (uint32_t k = begin; k < end; k++) sum += weights->weights[k];
            if (begin == end || !(sum > 0)) {
                for (int r = 0; r < 3; r++) frame[3 * v + r] = p[r];
                continue;
            }
            for (uint32_t k = begin; k < end; k++) {
                const double *s = skin + 16 * weights->bones[k];
                double w = normalised[k];
                for (int r = 0; r < 3; r++)
                    acc[r] += w * (s[0 * 4 + r] * p[0] + s[1 * 4 + r] * p[1] + s[2 * 4 + r] * p[2] + s[12 + r]);
            }
            for (int r = 0; r < 3; r++) {
                frame[3 * v + r] = (float)acc[r];
                if (!isfinite(frame[3 * v + r])) {
                    status = lk_error_set(error, LK_ERR_RANGE, "frame %zu: vertex %zu skins to a non-finite position",
                                          f + 1, v + 1);
                    goto done;
                }
            }
        }
    }
    if (vertex_count) memcpy(out->mesh.positions, out->frame_positions, vertex_count * 3 * sizeof(float));
done:
    free(base);
    free(pose);
    free(skin);
    free(normalised);
    if (status != LK_OK) lk_animation_free(out);
    return status;
}
