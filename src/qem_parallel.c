/* SPDX-License-Identifier: MIT */
/*
 * QEM simplification on several threads (lk_simplify_options.thread_count).
 *
 * The cleaned mesh is cut into part_count slabs of equal triangle counts
 * along the longest side of its bounding box (by triangle centroid). Each
 * slab is an ordinary QEM run (src/qem.c) on its own thread, in the whole
 * mesh's units (so costs and max_error mean the same in every slab), with
 * the vertices it shares with another slab locked. Those vertices keep the
 * input's spacing along the cut, so each slab is given its share of the
 * target plus one triangle and one vertex per locked vertex, the seam's
 * expected surplus. The slabs are joined, and the band of triangles within
 * BAND_RINGS rings of the cut is simplified once more, its rim locked, by as
 * many triangles (or vertices) as the join has above the target.
 *
 * Why slabs: the cut stays at input resolution until the band pass, so the
 * shorter the cut the less work and error the band adds; one axis keeps it
 * a single cross-section per pair of slabs.
 *
 * Deterministic for a given part count: every slab runs alone on its own
 * copy, and joins go in slab order. The band pass sees the joined mesh, not
 * the input, so its quadrics start from the slabs' result (the error it
 * reports is measured against that).
 */
#include "internal.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

enum { BAND_RINGS = 3, MAX_PARTS = 64 };
#define NONE UINT32_MAX

typedef struct part_job {
    const lk_mesh *mesh;          /* the whole mesh (not cleaned: each slab is) */
    const unsigned char *part_of; /* triangle -> slab */
    const unsigned char *shared;  /* vertex -> used by several slabs */
    unsigned index;
    size_t clean_triangles; /* the slab's triangles once cleaned */
    lk_simplify_options options;
    lk__qem_part frame;
    uint32_t *global_of; /* slab vertex -> whole-mesh vertex */
    size_t vertex_count; /* slab vertices */
    lk_simplify_result result;
    lk_status status;
    lk_error error;
    atomic_int *cancelled;
    lk_progress_fn progress; /* slab 0 only: it runs on the caller's thread */
    void *progress_user;
} part_job;

/* LK_ATTR_* flags of the attributes `mesh` has (radii are not simplified) */
static unsigned attribute_flags(const lk_mesh *mesh)
{
    return (mesh->normals ? LK_ATTR_NORMALS : 0) | (mesh->texcoords ? LK_ATTR_TEXCOORDS : 0) |
           (mesh->colors ? LK_ATTR_COLORS : 0);
}

/* dst vertex d takes the position and attributes of src vertex s (both
 * meshes have the same attributes) */
static void copy_vertex(lk_mesh *dst, size_t d, const lk_mesh *src, size_t s)
{
    memcpy(dst->positions + 3 * d, src->positions + 3 * s, 3 * sizeof(float));
    if (dst->normals) memcpy(dst->normals + 3 * d, src->normals + 3 * s, 3 * sizeof(float));
    if (dst->texcoords) memcpy(dst->texcoords + 2 * d, src->texcoords + 2 * s, 2 * sizeof(float));
    if (dst->colors) memcpy(dst->colors + 4 * d, src->colors + 4 * s, 4 * sizeof(float));
}

/* What the slabs' and the band's runs return (no history: LK_SIMPLIFY_RECORD
 * takes one thread). Not lk_simplify_result_free: src/simplify.c calls in
 * here, and modules call one way. */
static void free_run(lk_simplify_result *run)
{
    lk_mesh_free(&run->mesh);
    free(run->vertex_map);
    memset(run, 0, sizeof *run);
}

/* Copies slab job->index out of the whole mesh: its triangles, the
 * vertices they use (numbered in first use), their attributes, and which
 * of them are shared. */
static lk_status extract_part(part_job *job, lk_mesh *sub, unsigned char **locked, lk_error *error)
{
    const lk_mesh *mesh = job->mesh;
    size_t triangle_count = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) triangle_count += job->part_of[t] == job->index;
    size_t capacity = 3 * triangle_count < mesh->vertex_count ? 3 * triangle_count : mesh->vertex_count;
    uint32_t *local_of = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
    job->global_of = lk__malloc_array(capacity ? capacity : 1, sizeof(uint32_t));
    uint32_t *indices = lk__malloc_array(3 * triangle_count + 1, sizeof(uint32_t));
    if (!local_of || !job->global_of || !indices) {
        free(local_of), free(indices);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate a slab of %zu triangles", triangle_count);
    }
    memset(local_of, 0xFF, mesh->vertex_count * sizeof(uint32_t));
    size_t vertex_count = 0, written = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        if (job->part_of[t] != job->index) continue;
        for (int k = 0; k < 3; k++) {
            uint32_t g = mesh->indices[3 * t + k];
            if (local_of[g] == NONE) {
                local_of[g] = (uint32_t)vertex_count;
                job->global_of[vertex_count++] = g;
            }
            indices[written++] = local_of[g];
        }
    }
    free(local_of);
    job->vertex_count = vertex_count;
    lk_status status = lk_mesh_alloc(sub, vertex_count, 0, attribute_flags(mesh), error);
    *locked = lk__malloc_array(vertex_count + 1, 1);
    if (status == LK_OK && !*locked) status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate slab locks");
    if (status != LK_OK) {
        free(indices);
        return status;
    }
    free(sub->indices);
    sub->indices = indices;
    sub->triangle_count = triangle_count;
    status = lk_mesh_remove_degenerate(sub, NULL, NULL, error);
    if (status != LK_OK) return status;
    for (size_t l = 0; l < vertex_count; l++) {
        size_t g = job->global_of[l];
        copy_vertex(sub, l, mesh, g);
        (*locked)[l] = job->shared[g];
    }
    return LK_OK;
}

static int part_progress(void *user, double fraction, const char *stage)
{
    part_job *job = user;
    if (atomic_load(job->cancelled)) return 1;
    if (job->progress && job->progress(job->progress_user, 0.9 * fraction, stage)) {
        atomic_store(job->cancelled, 1);
        return 1;
    }
    return 0;
}

/* A slab's share of a count target given for `whole` elements, the slab
 * having `part` of them, plus the seam's surplus; 0 stays 0 (no target). */
static size_t share(size_t whole_target, size_t part, size_t whole, size_t seam)
{
    if (whole_target == 0) return 0;
    return (size_t)llround((double)whole_target * (double)part / (double)whole) + seam;
}

static void *run_part(void *arg)
{
    part_job *job = arg;
    lk_mesh sub;
    lk_mesh_init(&sub);
    unsigned char *locked = NULL;
    job->status = extract_part(job, &sub, &locked, &job->error);
    job->clean_triangles = sub.triangle_count;
    if (job->status == LK_OK && sub.triangle_count > 0) {
        size_t locked_count = 0;
        for (size_t l = 0; l < job->vertex_count; l++) locked_count += locked[l];
        /* the ratio applies to the cleaned slab as it applies to the cleaned whole */
        bool triangle_target = job->options.target_ratio > 0 || job->options.target_triangles > 0;
        size_t ratio_share = (size_t)floor(job->options.target_ratio * (double)sub.triangle_count);
        size_t count_share = share(job->options.target_triangles, sub.triangle_count, job->mesh->triangle_count, 0);
        size_t triangles = ratio_share > count_share ? ratio_share : count_share;
        job->options.target_ratio = 0;
        job->options.target_triangles = triangle_target ? triangles + locked_count : 0;
        job->options.target_vertices =
            share(job->options.target_vertices, job->vertex_count, job->mesh->vertex_count, locked_count);
        job->frame.locked = locked;
        job->status =
            lk__simplify_qem_part(&sub, &job->options, &job->frame, &job->result, part_progress, job, &job->error);
    }
    lk_mesh_free(&sub);
    free(locked);
    if (job->status != LK_OK) atomic_store(job->cancelled, 1);
    return NULL;
}

/* Slab of every triangle: part_count slabs of equal counts along the
 * longest axis of the bounds min..max, by the sum of the corners'
 * coordinates (3x the centroid). */
static lk_status cut_slabs(const lk_mesh *mesh, const float min[3], const float max[3], unsigned part_count,
                           unsigned char *part_of, lk_error *error)
{
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (max[k] - min[k] > max[axis] - min[axis]) axis = k;
    size_t count = mesh->triangle_count;
    float *key = lk__malloc_array(count, sizeof(float));
    float *sorted = lk__malloc_array(count, sizeof(float));
    if (!key || !sorted) {
        free(key), free(sorted);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the slab keys");
    }
    for (size_t t = 0; t < count; t++) {
        /* summed in index order, so that repeats of a triangle (cleaned
         * on the slab's thread) fall in the same slab */
        uint32_t a = mesh->indices[3 * t], b = mesh->indices[3 * t + 1], c = mesh->indices[3 * t + 2], swap;
        if (a > b) swap = a, a = b, b = swap;
        if (b > c) swap = b, b = c, c = swap;
        if (a > b) swap = a, a = b, b = swap;
        key[t] = mesh->positions[3 * (size_t)a + axis] + mesh->positions[3 * (size_t)b + axis] +
                 mesh->positions[3 * (size_t)c + axis];
    }
    memcpy(sorted, key, count * sizeof(float));
    /* the slab boundaries: quantiles, each selected inside the range the
     * previous one left above it */
    float boundary[MAX_PARTS];
    size_t from = 0;
    for (unsigned p = 1; p < part_count; p++) {
        size_t rank = count * p / part_count;
        lk__select_float(sorted + from, count - from, rank - from);
        boundary[p - 1] = sorted[rank];
        from = rank;
    }
    free(sorted);
    for (size_t t = 0; t < count; t++) {
        unsigned p = 0;
        while (p + 1 < part_count && key[t] >= boundary[p]) p++;
        part_of[t] = (unsigned char)p;
    }
    free(key);
    return LK_OK;
}

/* The joined slabs: vertices numbered slab by slab, each shared vertex
 * once (where it first survives), and the whole mesh's vertex map. */
typedef struct joined {
    lk_mesh mesh;
    uint32_t *map;           /* whole-mesh vertex -> joined vertex */
    unsigned char *is_cut;   /* joined vertex -> a shared vertex */
    double error;            /* largest slab error */
    bool every_part_reached; /* every slab reached its targets */
} joined;

static lk_status join_parts(const lk_mesh *mesh, const unsigned char *shared, part_job *jobs, unsigned part_count,
                            joined *out, lk_error *error)
{
    size_t total_vertices = 0, total_triangles = 0;
    for (unsigned p = 0; p < part_count; p++) {
        total_vertices += jobs[p].result.mesh.vertex_count;
        total_triangles += jobs[p].result.mesh.triangle_count;
    }
    out->map = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
    uint32_t *remap = lk__malloc_array(total_vertices + 1, sizeof(uint32_t)); /* slab output -> joined */
    lk_status status = out->map && remap ? LK_OK : lk_error_set(error, LK_ERR_NOMEM, "cannot join the slabs");
    if (status != LK_OK) {
        free(remap);
        return status;
    }
    memset(out->map, 0xFF, mesh->vertex_count * sizeof(uint32_t));
    memset(remap, 0xFF, (total_vertices + 1) * sizeof(uint32_t));
    /* outputs of shared vertices seen in an earlier slab take its number;
     * the others are numbered in slab order */
    size_t joined_count = 0, base = 0;
    out->error = 0;
    out->every_part_reached = true;
    for (unsigned p = 0; p < part_count; p++) {
        part_job *job = &jobs[p];
        const lk_simplify_result *r = &job->result;
        for (size_t l = 0; l < job->vertex_count; l++) {
            uint32_t g = job->global_of[l], o = r->vertex_map ? r->vertex_map[l] : NONE;
            if (o != NONE && shared[g] && out->map[g] != NONE) remap[base + o] = out->map[g];
        }
        for (size_t o = 0; o < r->mesh.vertex_count; o++)
            if (remap[base + o] == NONE) remap[base + o] = (uint32_t)joined_count++;
        for (size_t l = 0; l < job->vertex_count && r->vertex_map; l++) {
            uint32_t o = r->vertex_map[l];
            if (o != NONE) out->map[job->global_of[l]] = remap[base + o];
        }
        base += r->mesh.vertex_count;
        if (r->error > out->error) out->error = r->error;
        if (!r->target_reached && job->clean_triangles > 0) out->every_part_reached = false;
    }
    status = lk_mesh_alloc(&out->mesh, joined_count, total_triangles, attribute_flags(mesh), error);
    out->is_cut = status == LK_OK ? lk__calloc_array(joined_count + 1, 1) : NULL;
    if (status == LK_OK && !out->is_cut) status = lk_error_set(error, LK_ERR_NOMEM, "cannot join the slabs");
    if (status == LK_OK) {
        lk_mesh *m = &out->mesh;
        size_t triangles = 0;
        base = 0;
        for (unsigned p = 0; p < part_count; p++) {
            const lk_mesh *r = &jobs[p].result.mesh;
            for (size_t o = 0; o < r->vertex_count; o++) copy_vertex(m, remap[base + o], r, o);
            for (size_t i = 0; i < 3 * r->triangle_count; i++)
                m->indices[3 * triangles + i] = remap[base + r->indices[i]];
            triangles += r->triangle_count;
            base += r->vertex_count;
        }
        for (size_t g = 0; g < mesh->vertex_count; g++)
            if (shared[g] && out->map[g] != NONE) out->is_cut[out->map[g]] = 1;
    }
    free(remap);
    return status;
}

/* The band pass on the joined mesh: triangles within BAND_RINGS rings of
 * a cut vertex, simplified by the joined mesh's surplus over the targets
 * (or to max_error alone when no count is asked), their rim locked. Fills
 * result->mesh and result->vertex_map (whole-mesh vertex -> output). */
static lk_status band_pass(const lk_mesh *mesh, const lk_simplify_options *options, joined *join,
                           size_t target_triangles, size_t target_vertices, const lk__qem_part *frame,
                           lk_simplify_result *result, lk_error *error)
{
    lk_mesh *m = &join->mesh;
    size_t vertex_count = m->vertex_count, triangle_count = m->triangle_count;
    bool count_target = target_triangles > 0 || target_vertices > 0;
    size_t surplus_triangles =
        target_triangles && triangle_count > target_triangles ? triangle_count - target_triangles : 0;
    size_t surplus_vertices = target_vertices && vertex_count > target_vertices ? vertex_count - target_vertices : 0;
    unsigned char *ring = lk__malloc_array(vertex_count + 1, 1);
    unsigned char *in_band = lk__malloc_array(triangle_count + 1, 1);
    unsigned char *rim = lk__calloc_array(vertex_count + 1, 1);
    uint32_t *band_of = lk__malloc_array(vertex_count + 1, sizeof(uint32_t));  /* joined -> band vertex */
    uint32_t *final_of = lk__malloc_array(vertex_count + 1, sizeof(uint32_t)); /* joined -> output */
    lk_mesh band;
    lk_mesh_init(&band);
    lk_simplify_result banded;
    memset(&banded, 0, sizeof banded);
    unsigned char *band_locked = NULL;
    uint32_t *joined_of = NULL;
    lk_status status = ring && in_band && rim && band_of && final_of
                           ? LK_OK
                           : lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the band around the cut");
    size_t band_triangles = 0, band_vertices = 0;
    if (status == LK_OK) {
        for (size_t v = 0; v < vertex_count; v++) ring[v] = join->is_cut[v] ? 0 : 255;
        for (unsigned r = 1; r < BAND_RINGS; r++)
            for (size_t t = 0; t < triangle_count; t++) {
                const uint32_t *c = m->indices + 3 * t;
                if (ring[c[0]] != r - 1 && ring[c[1]] != r - 1 && ring[c[2]] != r - 1) continue;
                for (int k = 0; k < 3; k++)
                    if (ring[c[k]] > r) ring[c[k]] = (unsigned char)r;
            }
        for (size_t t = 0; t < triangle_count; t++) {
            const uint32_t *c = m->indices + 3 * t;
            in_band[t] = ring[c[0]] < BAND_RINGS || ring[c[1]] < BAND_RINGS || ring[c[2]] < BAND_RINGS;
            band_triangles += in_band[t];
            if (!in_band[t])
                for (int k = 0; k < 3; k++) rim[c[k]] = 1; /* used outside the band: kept as is */
        }
        memset(band_of, 0xFF, (vertex_count + 1) * sizeof(uint32_t));
        for (size_t t = 0; t < triangle_count; t++)
            if (in_band[t])
                for (int k = 0; k < 3; k++)
                    if (band_of[m->indices[3 * t + k]] == NONE)
                        band_of[m->indices[3 * t + k]] = (uint32_t)band_vertices++;
    }
    bool run = status == LK_OK && band_triangles > 0 && (count_target ? surplus_triangles || surplus_vertices : true);
    if (run) {
        status = lk_mesh_alloc(&band, band_vertices, band_triangles, attribute_flags(m), error);
        band_locked = status == LK_OK ? lk__malloc_array(band_vertices, 1) : NULL;
        joined_of = status == LK_OK ? lk__malloc_array(band_vertices, sizeof(uint32_t)) : NULL;
        if (status == LK_OK && (!band_locked || !joined_of))
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the band around the cut");
    }
    if (run && status == LK_OK) {
        size_t written = 0;
        for (size_t t = 0; t < triangle_count; t++)
            if (in_band[t])
                for (int k = 0; k < 3; k++) band.indices[written++] = band_of[m->indices[3 * t + k]];
        for (size_t v = 0; v < vertex_count; v++) {
            uint32_t b = band_of[v];
            if (b == NONE) continue;
            joined_of[b] = (uint32_t)v;
            band_locked[b] = rim[v];
            copy_vertex(&band, b, m, v);
        }
        lk_simplify_options band_options = *options;
        band_options.target_ratio = 0;
        /* 1, not 0 (no target), when the surplus exceeds the band: as far as the rim allows */
        band_options.target_triangles =
            surplus_triangles ? (band_triangles > surplus_triangles ? band_triangles - surplus_triangles : 1) : 0;
        band_options.target_vertices =
            surplus_vertices ? (band_vertices > surplus_vertices ? band_vertices - surplus_vertices : 1) : 0;
        lk__qem_part band_frame = *frame;
        band_frame.locked = band_locked;
        status = lk__simplify_qem_part(&band, &band_options, &band_frame, &banded, NULL, NULL, error);
    }
    if (status == LK_OK) {
        /* output: the joined vertices outside the band's inside, then the
         * band's new ones; triangles likewise */
        const lk_mesh *b = &banded.mesh;
        size_t out_vertices = 0;
        for (size_t v = 0; v < vertex_count; v++)
            final_of[v] = run && band_of[v] != NONE && !rim[v] ? NONE : (uint32_t)out_vertices++;
        uint32_t *band_out = lk__malloc_array(b->vertex_count + 1, sizeof(uint32_t));
        if (!band_out) status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the output");
        size_t out_triangles = 0;
        if (status == LK_OK) {
            memset(band_out, 0xFF, (b->vertex_count + 1) * sizeof(uint32_t));
            if (run) {
                for (size_t l = 0; l < band_vertices; l++) /* the rim keeps its number */
                    if (band_locked[l] && banded.vertex_map[l] != NONE)
                        band_out[banded.vertex_map[l]] = final_of[joined_of[l]];
                for (size_t o = 0; o < b->vertex_count; o++)
                    if (band_out[o] == NONE) band_out[o] = (uint32_t)out_vertices++;
                /* band vertices that vanished follow the band's map */
                for (size_t l = 0; l < band_vertices; l++)
                    if (!band_locked[l])
                        final_of[joined_of[l]] = banded.vertex_map[l] == NONE ? NONE : band_out[banded.vertex_map[l]];
            }
            out_triangles = run ? triangle_count - band_triangles + b->triangle_count : triangle_count;
            status = lk_mesh_alloc(&result->mesh, out_vertices, out_triangles, attribute_flags(m), error);
        }
        if (status == LK_OK) {
            lk_mesh *out = &result->mesh;
            for (size_t v = 0; v < vertex_count; v++)
                if (!(run && band_of[v] != NONE && !rim[v])) copy_vertex(out, final_of[v], m, v);
            for (size_t o = 0; run && o < b->vertex_count; o++) copy_vertex(out, band_out[o], b, o);
            size_t written = 0;
            for (size_t t = 0; t < triangle_count; t++) {
                if (run && in_band[t]) continue;
                for (int k = 0; k < 3; k++) out->indices[written++] = final_of[m->indices[3 * t + k]];
            }
            for (size_t i = 0; run && i < 3 * b->triangle_count; i++) out->indices[written++] = band_out[b->indices[i]];
            result->vertex_map = join->map; /* rewritten in place: whole -> joined -> output */
            join->map = NULL;
            for (size_t g = 0; g < mesh->vertex_count; g++) {
                uint32_t j = result->vertex_map[g];
                result->vertex_map[g] = j == NONE ? NONE : final_of[j];
            }
            result->error = join->error > banded.error ? join->error : banded.error;
            bool count_reached = (target_triangles && out_triangles <= target_triangles) ||
                                 (target_vertices && out_vertices <= target_vertices);
            /* as lk__simplify_qem: a count target, or the error bound that stopped it */
            bool stopped_by_error =
                options->max_error > 0 && join->every_part_reached && (!run || banded.target_reached);
            result->target_reached = count_target ? count_reached || stopped_by_error : 1;
        }
        free(band_out);
    }
    free_run(&banded);
    lk_mesh_free(&band);
    free(ring), free(in_band), free(rim), free(band_of), free(final_of), free(band_locked), free(joined_of);
    return status;
}

lk_status lk__simplify_qem_parallel(const lk_mesh *mesh, const lk_simplify_options *options, unsigned part_count,
                                    lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                    lk_error *error)
{
    if (options->flags & LK_SIMPLIFY_RECORD)
        return lk_error_set(error, LK_ERR_INVALID, "the contraction history (record) needs one thread");
    if (part_count < 2 || part_count > MAX_PARTS)
        return lk_error_set(error, LK_ERR_INVALID, "QEM on %u slabs: 2 to %d", part_count, MAX_PARTS);

    unsigned char *part_of = lk__malloc_array(mesh->triangle_count, 1);
    unsigned char *owner = lk__malloc_array(mesh->vertex_count + 1, 1);
    unsigned char *shared = lk__calloc_array(mesh->vertex_count + 1, 1);
    part_job *jobs = lk__calloc_array(part_count, sizeof(part_job));
    lk_status status =
        part_of && owner && shared && jobs ? LK_OK : lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the slabs");
    float min[3], max[3];
    lk_mesh_bounds(mesh, min, max);
    if (status == LK_OK) status = cut_slabs(mesh, min, max, part_count, part_of, error);
    lk__qem_part frame;
    memset(&frame, 0, sizeof frame);
    if (status == LK_OK) {
        memset(owner, 0xFF, mesh->vertex_count);
        for (size_t t = 0; t < mesh->triangle_count; t++)
            for (int k = 0; k < 3; k++) {
                uint32_t v = mesh->indices[3 * t + k];
                if (owner[v] == 0xFF)
                    owner[v] = part_of[t];
                else if (owner[v] != part_of[t])
                    shared[v] = 1;
            }
        /* the whole mesh's units, as src/qem_build.c sets them */
        double dx = (double)max[0] - min[0], dy = (double)max[1] - min[1], dz = (double)max[2] - min[2];
        double diagonal = sqrt(dx * dx + dy * dy + dz * dz);
        for (int k = 0; k < 3; k++) frame.center[k] = 0.5 * ((double)min[k] + (double)max[k]);
        frame.extent = diagonal > 0 ? diagonal : 1;
    }
    free(owner);
    atomic_int cancelled;
    atomic_init(&cancelled, 0);
    pthread_t threads[MAX_PARTS];
    bool started[MAX_PARTS] = {false};
    if (status == LK_OK) {
        for (unsigned p = 0; p < part_count; p++) {
            part_job *job = &jobs[p];
            job->mesh = mesh;
            job->part_of = part_of;
            job->shared = shared;
            job->index = p;
            job->options = *options;
            job->frame = frame;
            job->cancelled = &cancelled;
            if (p == 0) job->progress = progress, job->progress_user = progress_user;
        }
        /* slab 0 on this thread (it reports progress); a slab whose thread
         * cannot start runs here too, after it: same result, later */
        for (unsigned p = 1; p < part_count; p++)
            started[p] = pthread_create(&threads[p], NULL, run_part, &jobs[p]) == 0;
        run_part(&jobs[0]);
        for (unsigned p = 1; p < part_count; p++) {
            if (started[p])
                pthread_join(threads[p], NULL);
            else
                run_part(&jobs[p]);
        }
        for (unsigned p = 0; p < part_count && status == LK_OK; p++)
            if (jobs[p].status != LK_OK) {
                status = jobs[p].status;
                if (error) *error = jobs[p].error;
            }
        /* a slab stopped by another's failure reports "cancelled": prefer the real cause */
        for (unsigned p = 0; p < part_count; p++)
            if (jobs[p].status != LK_OK && strcmp(jobs[p].error.message, "cancelled") != 0) {
                status = jobs[p].status;
                if (error) *error = jobs[p].error;
                break;
            }
    }
    free(part_of);
    /* the whole's triangle target, as lk__simplify_qem computes it on the
     * cleaned mesh (0 = none) */
    size_t clean_triangles = 0, target_triangles = 0;
    for (unsigned p = 0; p < part_count && jobs; p++) clean_triangles += jobs[p].clean_triangles;
    if (status == LK_OK && clean_triangles == 0)
        status = lk_error_set(error, LK_ERR_INVALID, "every triangle is degenerate: nothing to simplify");
    if (options->target_ratio > 0) target_triangles = (size_t)floor(options->target_ratio * (double)clean_triangles);
    if (options->target_triangles > target_triangles) target_triangles = options->target_triangles;
    joined join;
    memset(&join, 0, sizeof join);
    if (status == LK_OK) status = join_parts(mesh, shared, jobs, part_count, &join, error);
    free(shared);
    for (unsigned p = 0; p < part_count && jobs; p++) {
        free_run(&jobs[p].result);
        free(jobs[p].global_of);
    }
    free(jobs);
    if (status == LK_OK && progress && progress(progress_user, 0.9, "simplify across the cuts"))
        status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    if (status == LK_OK)
        status = band_pass(mesh, options, &join, target_triangles, options->target_vertices, &frame, result, error);
    lk_mesh_free(&join.mesh);
    free(join.map), free(join.is_cut);
    return status;
}
