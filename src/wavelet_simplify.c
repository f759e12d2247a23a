/* SPDX-License-Identifier: MIT */
/* The LK_SIMPLIFY_WAVELET method of lk_simplify (Jang, Lee, Han & Park
 * 2004): slice the mesh into contours (slice.c), simplify each contour with
 * wavelets (wavelet.c), tile the contours of neighbouring planes back into a
 * closed mesh (tile.c), then refine between the planes (here). A count
 * target becomes the contours' vertex target (and, when slice_count is 0,
 * picks the slice count among a few candidates). docs/wavelet.md explains
 * the choices.
 *
 * Pipeline. With a count target, a share of the vertex budget is kept for
 * the refinement between the planes (see below): the tiled surface has all
 * its vertices on the slice planes, and its worst errors lie between them. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The paper's slice count. */
#define PAPER_SLICES 150

typedef struct wavelet_run {
    lk_slices slices;
    lk_slices simplified;
    lk_contour_simplify_info info;
} wavelet_run;

static void wavelet_run_free(wavelet_run *run)
{
    lk_slices_free(&run->slices);
    lk_slices_free(&run->simplified);
}

static lk_status run_slices(const lk_mesh *mesh, lk_axis axis, size_t slice_count,
                            const lk_contour_simplify_options *contour_options, wavelet_run *run,
                            lk_progress_fn progress, void *progress_user, lk_error *error)
{
    memset(run, 0, sizeof *run);
    lk_status status = lk_mesh_slice(mesh, axis, slice_count, &run->slices, progress, progress_user, error);
    if (status == LK_OK)
        status = lk_slices_simplify(&run->slices, contour_options, &run->simplified, &run->info, progress,
                                    progress_user, error);
    if (status != LK_OK) wavelet_run_free(run);
    return status;
}

/* ---- refinement between the planes -------------------------------------- */

/* Every tiled vertex lies on a slice plane, so whatever the surface does
 * between two planes (a feature tip that starts and ends between them, the
 * saddle under a branching, a belly a bridge spans) is invisible to the
 * contours: it is where the largest (Hausdorff) errors sit. The
 * refinement spends a small reserve of the vertex budget there: in rounds,
 * it measures both ways (input vertices and triangle centres to the
 * output; points of every output triangle to the input), and at the worst
 * places inserts a vertex lying on the input surface: the input point
 * itself, or the input point nearest to the output point. The vertex splits
 * the output triangle (or its edge, when the place is near one), which keeps
 * the mesh a closed, consistently oriented 2-manifold. */

/* Share of a vertex target kept for the refinement. */
#define REFINE_SHARE 0.08
/* Rounds the reserve is spread over (the measure is redone each round). */
#define REFINE_ROUNDS 6
/* Barycentric coordinate below which a place counts as on the edge. */
#define REFINE_EDGE 0.2
/* Places nearer than this share of the largest distance wait for a later
 * round. */
#define REFINE_FAR 0.25
/* Input triangles whose longest edge is shorter than this share of the
 * output's mean edge are represented by their corners alone (a point of
 * the triangle is within its edge length of a corner). */
#define REFINE_SMALL_TRIANGLE 0.25
/* A new triangle may lie at most this many times the error it fixes from
 * the input. */
#define REFINE_SPIKE 1.5

typedef struct refine_place {
    double distance;
    double position[3]; /* the new vertex: a point of the input surface */
    double bary[3];     /* where in the output triangle */
    uint32_t triangle;
} refine_place;

static int refine_place_order(const void *a, const void *b)
{
    const refine_place *p = a, *q = b;
    if (p->distance != q->distance) return p->distance < q->distance ? 1 : -1;
    if (p->triangle != q->triangle) return p->triangle < q->triangle ? -1 : 1;
    return 0;
}

/* Barycentric coordinates of the projection of p onto triangle abc. */
static void barycentric(const float *a, const float *b, const float *c, const double *p, double *out)
{
    double e0[3], e1[3], d[3];
    for (int k = 0; k < 3; k++) {
        e0[k] = (double)b[k] - a[k];
        e1[k] = (double)c[k] - a[k];
        d[k] = p[k] - a[k];
    }
    double d00 = e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2], d01 = e0[0] * e1[0] + e0[1] * e1[1] + e0[2] * e1[2];
    double d11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    double d20 = d[0] * e0[0] + d[1] * e0[1] + d[2] * e0[2], d21 = d[0] * e1[0] + d[1] * e1[1] + d[2] * e1[2];
    double det = d00 * d11 - d01 * d01;
    if (!(det > 0)) {
        out[0] = out[1] = out[2] = 1.0 / 3;
        return;
    }
    double v = (d11 * d20 - d01 * d21) / det, w = (d00 * d21 - d01 * d20) / det;
    out[0] = 1 - v - w;
    out[1] = v;
    out[2] = w;
}

/* The triangle other than t that holds the edge b -> a (t holds a -> b). */
static size_t opposite_triangle(const lk_mesh *mesh, size_t t, uint32_t a, uint32_t b)
{
    for (size_t s = 0; s < mesh->triangle_count; s++) {
        if (s == t) continue;
        const uint32_t *i = mesh->indices + 3 * s;
        for (int e = 0; e < 3; e++)
            if (i[e] == b && i[(e + 1) % 3] == a) return s;
    }
    return SIZE_MAX;
}

/* Barycentric sample points of an output triangle: edge midpoints and
 * quarter points (a band's long edges span the gap between planes), centre
 * and the points between the centre and the corners. */
#define REFINE_SAMPLES 13
static const double refine_samples[REFINE_SAMPLES][3] = {{0.5, 0.5, 0},
                                                         {0, 0.5, 0.5},
                                                         {0.5, 0, 0.5},
                                                         {0.75, 0.25, 0},
                                                         {0.25, 0.75, 0},
                                                         {0, 0.75, 0.25},
                                                         {0, 0.25, 0.75},
                                                         {0.25, 0, 0.75},
                                                         {0.75, 0, 0.25},
                                                         {1.0 / 3, 1.0 / 3, 1.0 / 3},
                                                         {2.0 / 3, 1.0 / 6, 1.0 / 6},
                                                         {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                                         {1.0 / 6, 1.0 / 6, 2.0 / 3}};

/* Largest distance from the sample points of triangle t to the input. */
static double triangle_distance(const lk_mesh *mesh, size_t t, const lk_surface_index *input_index, double *closest,
                                const double **bary)
{
    const uint32_t *tri = mesh->indices + 3 * t;
    double worst = -1;
    for (int s = 0; s < REFINE_SAMPLES; s++) {
        double p[3], q[3];
        for (int k = 0; k < 3; k++)
            p[k] = refine_samples[s][0] * mesh->positions[3 * (size_t)tri[0] + k] +
                   refine_samples[s][1] * mesh->positions[3 * (size_t)tri[1] + k] +
                   refine_samples[s][2] * mesh->positions[3 * (size_t)tri[2] + k];
        double d = lk_surface_index_nearest(input_index, p, INFINITY, q, NULL);
        if (d > worst) {
            worst = d;
            if (closest) memcpy(closest, q, sizeof q);
            if (bary) *bary = refine_samples[s];
        }
    }
    return worst;
}

/* Inserts one vertex; `touched` marks triangles changed in this round.
 * Returns 1 when inserted, 0 when skipped: the place touches a triangle
 * already changed, the vertex would coincide with a corner, or a new
 * triangle would lie farther from the input than `spike` times the error
 * being fixed (a spike across empty space; the change is undone). The mesh arrays have
 * room for it. */
static int refine_insert(lk_mesh *mesh, const refine_place *place, unsigned char *touched, double merge, double spike,
                         const lk_surface_index *input_index)
{
    size_t t = place->triangle;
    if (touched[t]) return 0;
    uint32_t *tri = mesh->indices + 3 * t;
    for (int k = 0; k < 3; k++) {
        const float *corner = mesh->positions + 3 * (size_t)tri[k];
        double dx = place->position[0] - corner[0], dy = place->position[1] - corner[1],
               dz = place->position[2] - corner[2];
        if (dx * dx + dy * dy + dz * dz <= merge * merge) return 0;
    }
    uint32_t m = (uint32_t)mesh->vertex_count;
    int smallest = 0;
    for (int k = 1; k < 3; k++)
        if (place->bary[k] < place->bary[smallest]) smallest = k;
    size_t added = mesh->triangle_count, s = SIZE_MAX;
    uint32_t saved_t[3], saved_s[3];
    memcpy(saved_t, tri, sizeof saved_t);
    if (place->bary[smallest] < REFINE_EDGE) {
        /* Split the edge opposite the corner with the smallest weight:
         * t = (a, b, c) with edge a -> b, s = (b, a, d). */
        uint32_t a = tri[(smallest + 1) % 3], b = tri[(smallest + 2) % 3], c = tri[smallest];
        s = opposite_triangle(mesh, t, a, b);
        if (s == SIZE_MAX || touched[s]) return 0;
        uint32_t *other = mesh->indices + 3 * s;
        memcpy(saved_s, other, sizeof saved_s);
        uint32_t d = other[0] != a && other[0] != b ? other[0] : other[1] != a && other[1] != b ? other[1] : other[2];
        const float *pd = mesh->positions + 3 * (size_t)d;
        double dx = place->position[0] - pd[0], dy = place->position[1] - pd[1], dz = place->position[2] - pd[2];
        if (dx * dx + dy * dy + dz * dz <= merge * merge) return 0;
        tri[0] = a, tri[1] = m, tri[2] = c;
        other[0] = m, other[1] = a, other[2] = d;
        uint32_t *n = mesh->indices + 3 * added;
        n[0] = m, n[1] = b, n[2] = c;
        n[3] = b, n[4] = m, n[5] = d;
    } else {
        uint32_t a = tri[0], b = tri[1], c = tri[2];
        tri[2] = m;
        uint32_t *n = mesh->indices + 3 * added;
        n[0] = b, n[1] = c, n[2] = m;
        n[3] = c, n[4] = a, n[5] = m;
    }
    mesh->triangle_count += 2;
    for (int k = 0; k < 3; k++) {
        /* Near FLT_MAX a refined position may round past the float range. */
        double value = place->position[k];
        mesh->positions[3 * (size_t)m + k] = value > FLT_MAX ? FLT_MAX : value < -FLT_MAX ? -FLT_MAX : (float)value;
    }
    mesh->vertex_count++;
    size_t changed[4] = {t, added, added + 1, s};
    for (int i = 0; i < (s == SIZE_MAX ? 3 : 4); i++)
        if (triangle_distance(mesh, changed[i], input_index, NULL, NULL) > spike * place->distance) {
            memcpy(tri, saved_t, sizeof saved_t);
            if (s != SIZE_MAX) memcpy(mesh->indices + 3 * s, saved_s, sizeof saved_s);
            mesh->triangle_count -= 2;
            mesh->vertex_count--;
            return 0;
        }
    for (int i = 0; i < (s == SIZE_MAX ? 3 : 4); i++) touched[changed[i]] = 1;
    return 1;
}

/* Measures the output against the input both ways; fills places (the
 * worst first) and returns how many, or SIZE_MAX on allocation failure.
 * *worst gets the largest distance seen. */
static size_t refine_measure(const double *input_samples, size_t input_sample_count, double *sample_distance,
                             uint32_t *sample_triangle, const lk_surface_index *input_index, const lk_mesh *output,
                             refine_place *triangle_cache, unsigned char *dirty, refine_place **places,
                             size_t *capacity, double *worst, lk_status *status, lk_error *error)
{
    lk_surface_index *output_index = NULL;
    *status = lk_surface_index_build(output, &output_index, error);
    if (*status != LK_OK) return SIZE_MAX;
    size_t needed = input_sample_count + output->triangle_count;
    if (needed > *capacity) {
        refine_place *grown = lk__realloc_array(*places, needed, sizeof(refine_place));
        if (!grown) {
            lk_surface_index_free(output_index);
            *status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu refinement places", needed);
            return SIZE_MAX;
        }
        *places = grown;
        *capacity = needed;
    }
    size_t count = 0;
    *worst = 0;
    /* Input to output: the input point becomes the vertex. */
    for (size_t i = 0; i < input_sample_count; i++) {
        double p[3], closest[3];
        memcpy(p, input_samples + 3 * i, sizeof p);
        uint32_t triangle = 0;
        /* When the nearest triangle of the last measure is still there, the
         * distance can only have shrunk: that bounds the search. */
        double bound = sample_triangle[i] != UINT32_MAX && !dirty[sample_triangle[i]]
                           ? sample_distance[i] * (1 + 1e-9) + 1e-30
                           : INFINITY;
        double d = lk_surface_index_nearest(output_index, p, bound, closest, &triangle);
        if (!isfinite(d) && isfinite(bound))
            d = lk_surface_index_nearest(output_index, p, INFINITY, closest, &triangle);
        if (!isfinite(d)) continue;
        sample_distance[i] = d;
        sample_triangle[i] = triangle;
        refine_place *place = &(*places)[count++];
        place->distance = d;
        memcpy(place->position, p, sizeof p);
        place->triangle = triangle;
        const uint32_t *t = output->indices + 3 * (size_t)triangle;
        barycentric(output->positions + 3 * (size_t)t[0], output->positions + 3 * (size_t)t[1],
                    output->positions + 3 * (size_t)t[2], closest, place->bary);
        if (d > *worst) *worst = d;
    }
    /* Output to input: the nearest input point becomes the vertex. Only
     * triangles changed since the last measure are measured again. */
    for (size_t t = 0; t < output->triangle_count; t++) {
        refine_place *best = &triangle_cache[t];
        if (dirty[t]) {
            const double *bary = NULL;
            best->triangle = (uint32_t)t;
            best->distance = triangle_distance(output, t, input_index, best->position, &bary);
            if (bary)
                memcpy(best->bary, bary, sizeof best->bary);
            else
                best->distance = -1;
            dirty[t] = 0;
        }
        if (best->distance < 0) continue;
        (*places)[count++] = *best;
        if (best->distance > *worst) *worst = best->distance;
    }
    lk_surface_index_free(output_index);
    /* Only the far places can be used this round: sort those. */
    size_t kept = 0;
    for (size_t i = 0; i < count; i++)
        if ((*places)[i].distance >= REFINE_FAR * *worst) (*places)[kept++] = (*places)[i];
    qsort(*places, kept, sizeof(refine_place), refine_place_order);
    return kept;
}

/* Adds up to `budget` vertices to `output` where it is farthest from
 * `input` (see above), in REFINE_ROUNDS rounds. */
static lk_status refine_between_planes(const lk_mesh *input, const lk_surface_index *input_index, lk_mesh *output,
                                       size_t budget, double diagonal, lk_error *error)
{
    if (budget == 0 || output->triangle_count == 0) return LK_OK;
    size_t vertex_room = output->vertex_count + budget, triangle_room = output->triangle_count + 2 * budget;
    float *positions = lk__realloc_array(output->positions, 3 * vertex_room, sizeof(float));
    if (!positions) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement vertices");
    output->positions = positions;
    uint32_t *indices = lk__realloc_array(output->indices, 3 * triangle_room, sizeof(uint32_t));
    if (!indices) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement triangles");
    output->indices = indices;
    /* Input samples: every vertex, and the centres of the triangles that
     * are not small next to the output's. */
    double mean_edge = 0;
    for (size_t i = 0; i < 3 * output->triangle_count; i++) {
        const float *a = output->positions + 3 * (size_t)output->indices[i];
        const float *b = output->positions + 3 * (size_t)output->indices[i - i % 3 + (i + 1) % 3];
        mean_edge += sqrt(((double)a[0] - b[0]) * (a[0] - b[0]) + ((double)a[1] - b[1]) * (a[1] - b[1]) +
                          ((double)a[2] - b[2]) * (a[2] - b[2]));
    }
    mean_edge /= (double)(3 * output->triangle_count);
    double *input_samples = lk__malloc_array(4 * (input->vertex_count + input->triangle_count), sizeof(double));
    uint32_t *sample_triangle = lk__malloc_array(input->vertex_count + input->triangle_count, sizeof(uint32_t));
    unsigned char *touched = lk__malloc_array(triangle_room, 1);
    unsigned char *dirty = lk__malloc_array(triangle_room, 1);
    refine_place *triangle_cache = lk__malloc_array(triangle_room, sizeof(refine_place));
    if (!touched || !input_samples || !dirty || !triangle_cache || !sample_triangle) {
        free(touched);
        free(input_samples);
        free(sample_triangle);
        free(dirty);
        free(triangle_cache);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement samples");
    }
    memset(dirty, 1, triangle_room);
    size_t input_sample_count = 0;
    for (size_t v = 0; v < input->vertex_count; v++, input_sample_count++)
        for (int k = 0; k < 3; k++) input_samples[3 * input_sample_count + k] = input->positions[3 * v + k];
    for (size_t t = 0; t < input->triangle_count; t++) {
        const float *corner[3];
        for (int c = 0; c < 3; c++) corner[c] = input->positions + 3 * (size_t)input->indices[3 * t + c];
        double longest = 0;
        for (int c = 0; c < 3; c++) {
            const float *a = corner[c], *b = corner[(c + 1) % 3];
            longest = fmax(longest, sqrt(((double)a[0] - b[0]) * (a[0] - b[0]) + ((double)a[1] - b[1]) * (a[1] - b[1]) +
                                         ((double)a[2] - b[2]) * (a[2] - b[2])));
        }
        if (longest < REFINE_SMALL_TRIANGLE * mean_edge) continue;
        for (int k = 0; k < 3; k++)
            input_samples[3 * input_sample_count + k] = ((double)corner[0][k] + corner[1][k] + corner[2][k]) / 3;
        input_sample_count++;
    }
    /* Distances of the last measure, after the 3 coordinates per sample. */
    double *sample_distance = input_samples + 3 * input_sample_count;
    for (size_t i = 0; i < input_sample_count; i++) sample_triangle[i] = UINT32_MAX;
    refine_place *places = NULL;
    size_t capacity = 0;
    size_t per_round = (budget + REFINE_ROUNDS - 1) / REFINE_ROUNDS;
    double merge = 1e-6 * diagonal;
    lk_status status = LK_OK;
    /* The best mesh measured so far (insertions can make things worse
     * elsewhere): its counts and a copy of its arrays. */
    float *best_positions = lk__malloc_array(3 * vertex_room, sizeof(float));
    uint32_t *best_indices = lk__malloc_array(3 * triangle_room, sizeof(uint32_t));
    size_t best_vertices = output->vertex_count, best_triangles = output->triangle_count;
    double best_worst = INFINITY;
    if (!best_positions || !best_indices) {
        free(best_positions);
        free(best_indices);
        free(touched);
        free(input_samples);
        free(sample_triangle);
        free(dirty);
        free(triangle_cache);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement copies");
    }
    double spike = REFINE_SPIKE;
    for (;;) {
        double worst = 0;
        size_t count = refine_measure(input_samples, input_sample_count, sample_distance, sample_triangle, input_index,
                                      output, triangle_cache, dirty, &places, &capacity, &worst, &status, error);
        if (count == SIZE_MAX) break;
        if (worst <= best_worst) {
            best_worst = worst;
            best_vertices = output->vertex_count;
            best_triangles = output->triangle_count;
            memcpy(best_positions, output->positions, 3 * best_vertices * sizeof(float));
            memcpy(best_indices, output->indices, 3 * best_triangles * sizeof(uint32_t));
        } else {
            /* The last round made the largest error worse (its new
             * triangles were allowed up to REFINE_SPIKE times the error they
             * fixed): back to the best mesh, and go on with new triangles no
             * farther from the input than the error they fix. */
            output->vertex_count = best_vertices;
            output->triangle_count = best_triangles;
            memcpy(output->positions, best_positions, 3 * best_vertices * sizeof(float));
            memcpy(output->indices, best_indices, 3 * best_triangles * sizeof(uint32_t));
            memset(dirty, 1, triangle_room);
            if (spike <= 1) break;
            spike = 1;
            continue;
        }
        if (output->vertex_count >= vertex_room) break;
        size_t budget_left = vertex_room - output->vertex_count;
        memset(touched, 0, triangle_room);
        size_t inserted = 0, round_budget = per_round < budget_left ? per_round : budget_left;
        for (size_t i = 0; i < count && inserted < round_budget; i++) {
            if (places[i].distance <= 0) break;
            inserted += (size_t)refine_insert(output, &places[i], touched, merge, spike, input_index);
        }
        if (inserted == 0) break;
        for (size_t t = 0; t < output->triangle_count; t++) dirty[t] |= touched[t];
    }
    if (status == LK_OK && (output->vertex_count != best_vertices || output->triangle_count != best_triangles)) {
        output->vertex_count = best_vertices;
        output->triangle_count = best_triangles;
        memcpy(output->positions, best_positions, 3 * best_vertices * sizeof(float));
        memcpy(output->indices, best_indices, 3 * best_triangles * sizeof(uint32_t));
    }
    free(best_positions);
    free(best_indices);
    free(places);
    free(touched);
    free(input_samples);
    free(sample_triangle);
    free(dirty);
    free(triangle_cache);
    return status;
}

/* ---- holes ------------------------------------------------------------- */

/* Slicing needs a closed surface: a scan or a model with a few missing
 * triangles (the Chinese dragon sample has two 3-edge holes) is closed
 * first. Each boundary loop gets one triangle (3 edges) or a fan around a
 * new vertex at its centroid (more), oriented against the loop so the
 * orientation stays consistent. A boundary vertex with more than one way
 * on (two holes touching at a vertex) is left alone: slicing then refuses
 * the mesh with its usual message. Sets *closed to a copy (positions and
 * indices only: the output's vertices are new anyway) when there were
 * holes; returns the number closed in *hole_count. Meshes with more than
 * HOLE_EDGE_SHARE of their edges on a boundary are left open (refused). */
/* Largest share of boundary edges among all edges for which holes are
 * closed (the dragon: 6 of 29,994). */
#define HOLE_EDGE_SHARE 0.05

static lk_status close_holes(const lk_mesh *mesh, lk_mesh *closed, size_t *hole_count, lk_error *error)
{
    *hole_count = 0;
    lk_mesh_init(closed);
    lk_edge_adjacency edges;
    lk_status status = lk_edge_adjacency_build(mesh, &edges, error);
    if (status != LK_OK) return status;
    size_t boundary = 0;
    for (size_t e = 0; e < edges.edge_count; e++) boundary += edges.offsets[e + 1] - edges.offsets[e] == 1;
    uint32_t *next = NULL;
    uint32_t *loop_points = NULL;
    unsigned char *visited = NULL;
    /* An open sheet (a terrain, a single triangle) has no inside to close:
     * only a model missing a few triangles is closed here. */
    if (boundary == 0 || boundary > HOLE_EDGE_SHARE * (double)edges.edge_count) goto done;
    next = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
    visited = lk__calloc_array(mesh->vertex_count, 1);
    loop_points = lk__malloc_array(boundary, sizeof(uint32_t));
    if (!next || !visited || !loop_points) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the hole tables");
        goto done;
    }
    for (size_t v = 0; v < mesh->vertex_count; v++) next[v] = UINT32_MAX;
    /* A triangle's boundary edge a -> b: the hole runs b -> a. */
    for (size_t e = 0; e < edges.edge_count; e++) {
        if (edges.offsets[e + 1] - edges.offsets[e] != 1) continue;
        uint32_t t = edges.triangles[edges.offsets[e]];
        for (int c = 0; c < 3; c++) {
            if (edges.triangle_edges[3 * t + c] != e) continue;
            uint32_t a = mesh->indices[3 * t + c], b = mesh->indices[3 * t + (c + 1) % 3];
            if (next[b] != UINT32_MAX) goto done; /* two holes meet at b: not ours to guess */
            next[b] = a;
        }
    }
    /* New triangles: one per 3-edge loop, n per longer loop (fan). */
    size_t new_triangles = 0, new_vertices = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        if (next[v] == UINT32_MAX || visited[v]) continue;
        size_t length = 0;
        for (uint32_t w = (uint32_t)v; !visited[w]; w = next[w]) {
            visited[w] = 1;
            length++;
            if (next[w] == UINT32_MAX) goto done; /* an open chain: cannot happen in a valid mesh */
        }
        new_triangles += length == 3 ? 1 : length;
        new_vertices += length == 3 ? 0 : 1;
        (*hole_count)++;
    }
    status = lk_mesh_alloc(closed, mesh->vertex_count + new_vertices, mesh->triangle_count + new_triangles, 0, error);
    if (status != LK_OK) goto done;
    memcpy(closed->positions, mesh->positions, 3 * mesh->vertex_count * sizeof(float));
    memcpy(closed->indices, mesh->indices, 3 * mesh->triangle_count * sizeof(uint32_t));
    memset(visited, 0, mesh->vertex_count);
    size_t vertex = mesh->vertex_count, triangle = mesh->triangle_count;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        if (next[v] == UINT32_MAX || visited[v]) continue;
        size_t length = 0;
        for (uint32_t w = (uint32_t)v; !visited[w]; w = next[w]) {
            visited[w] = 1;
            loop_points[length++] = w;
        }
        uint32_t *tri = closed->indices + 3 * triangle;
        if (length == 3) {
            tri[0] = loop_points[0];
            tri[1] = loop_points[1];
            tri[2] = loop_points[2];
            triangle++;
            continue;
        }
        double centre[3] = {0, 0, 0};
        for (size_t i = 0; i < length; i++)
            for (int k = 0; k < 3; k++) centre[k] += mesh->positions[3 * (size_t)loop_points[i] + k] / (double)length;
        for (int k = 0; k < 3; k++) closed->positions[3 * vertex + k] = (float)centre[k];
        for (size_t i = 0; i < length; i++, triangle++) {
            tri = closed->indices + 3 * triangle;
            tri[0] = loop_points[i];
            tri[1] = loop_points[(i + 1) % length];
            tri[2] = (uint32_t)vertex;
        }
        vertex++;
    }
done:
    if (status != LK_OK || closed->triangle_count == 0) {
        lk_mesh_free(closed);
        *hole_count = 0;
    }
    free(next);
    free(visited);
    free(loop_points);
    lk_edge_adjacency_free(&edges);
    return status;
}

static lk_status simplify_wavelet(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                                  lk_progress_fn progress, void *progress_user, lk_error *error)
{
    lk_wavelet_criterion criterion = (lk_wavelet_criterion)options->wavelet_criterion;
    if (criterion != LK_WAVELET_DISTANCE && criterion != LK_WAVELET_ENERGY)
        return lk_error_set(error, LK_ERR_INVALID, "unknown contour criterion %d", options->wavelet_criterion);
    int refine = !(options->flags & LK_SIMPLIFY_NO_REFINE);
    if (options->slice_axis < LK_AXIS_AUTO || options->slice_axis > LK_AXIS_Z)
        return lk_error_set(error, LK_ERR_INVALID, "unknown slicing axis %d", options->slice_axis);
    lk_axis axis = (lk_axis)options->slice_axis;
    /* Count targets become a vertex count: the first one reached while
     * coarsening is the largest. A closed surface of genus 0 has
     * 2V - 4 triangles. */
    size_t target = 0;
    if (options->target_vertices) target = options->target_vertices;
    if (options->target_triangles) {
        size_t v = options->target_triangles / 2 + 2;
        if (v > target) target = v;
    }
    if (options->target_ratio > 0) {
        size_t v = (size_t)(options->target_ratio * (double)mesh->triangle_count / 2) + 2;
        if (v > target) target = v;
    }
    /* A count target keeps a reserve for the refinement between planes. */
    size_t contour_target = target;
    if (target > 0 && refine) contour_target = target - (size_t)ceil(REFINE_SHARE * (double)target);
    if (target > 0 && contour_target < 3) contour_target = target;
    lk_contour_simplify_options contour_options = {.target_vertices = contour_target, .criterion = criterion};
    wavelet_run run;
    lk_status status;
    size_t slice_count = options->slice_count;
    if (slice_count == 0) slice_count = PAPER_SLICES;
    if (options->max_error > 0) {
        /* The error bound is in-plane; it needs the diagonal first. */
        float low[3], high[3];
        contour_options.max_error = options->max_error * lk_mesh_bounds(mesh, low, high);
    }
    if (options->slice_count == 0 && target > 0) {
        /* Automatic count for a vertex budget: fewer slices leave more
         * points per contour. Score each candidate by the larger of its
         * in-plane error and its spacing (the tiling error between planes
         * grows like the spacing) and keep the best. */
        static const size_t candidates[] = {PAPER_SLICES, 100, 70, 50, 35, 25, 16, 11, 8};
        double best_score = INFINITY;
        size_t best_points = SIZE_MAX; /* when no candidate reaches the target: the nearest */
        memset(&run, 0, sizeof run);
        for (size_t c = 0; c < sizeof candidates / sizeof candidates[0]; c++) {
            wavelet_run trial;
            status = run_slices(mesh, axis, candidates[c], &contour_options, &trial, NULL, NULL, error);
            if (status != LK_OK) {
                wavelet_run_free(&run);
                return status;
            }
            double score = fmax(trial.info.error, trial.slices.spacing);
            if (!trial.info.target_reached) score = INFINITY;
            /* Contours that all collapsed (a model far larger along one
             * axis than the others) tile into nothing: a last resort. */
            size_t points = trial.simplified.contour_count ? trial.simplified.point_count : SIZE_MAX - 1;
            if (!trial.simplified.contour_count) score = INFINITY;
            /* Below the target, the best score; while none reaches it, the
             * fewest points (each contour keeps at least 3, so more
             * slices can overshoot the target by far). */
            if (score < best_score || (!isfinite(best_score) && points < best_points)) {
                if (c > 0) wavelet_run_free(&run);
                run = trial;
                best_score = score;
                best_points = points;
            } else {
                wavelet_run_free(&trial);
            }
            if (progress &&
                progress(progress_user, 0.75 * (double)(c + 1) / (double)(sizeof candidates / sizeof candidates[0]),
                         "choosing the slice count")) {
                wavelet_run_free(&run);
                return lk_error_set(error, LK_ERR_INVALID, "cancelled");
            }
        }
    } else {
        status = run_slices(mesh, axis, slice_count, &contour_options, &run, progress, progress_user, error);
        if (status != LK_OK) return status;
    }
    if (progress && progress(progress_user, 0.8, "tiling")) {
        wavelet_run_free(&run);
        return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    }
    status = lk_slices_tile(&run.simplified, &result->mesh, NULL, error);
    /* Tiling leaves out contours that pair with nothing on either side, so
     * a count target can end a little short: ask the contours for more
     * points (0.5 to 4 times the shortfall), keeping the closest result
     * that is not above the target. */
    static const double extra_factors[] = {0.5, 1, 1.5, 2, 3, 4};
    size_t shortfall =
        status == LK_OK && contour_target > result->mesh.vertex_count ? contour_target - result->mesh.vertex_count : 0;
    for (size_t retry = 0; retry < sizeof extra_factors / sizeof extra_factors[0] && status == LK_OK && target > 0 &&
                           run.info.target_reached && result->mesh.vertex_count < contour_target - contour_target / 100;
         retry++) {
        lk_contour_simplify_options more = contour_options;
        more.target_vertices = contour_target + (size_t)ceil(extra_factors[retry] * (double)shortfall);
        lk_slices simplified;
        lk_contour_simplify_info info;
        lk_mesh retiled;
        lk_mesh_init(&retiled);
        status = lk_slices_simplify(&run.slices, &more, &simplified, &info, NULL, NULL, error);
        if (status != LK_OK) break;
        status = lk_slices_tile(&simplified, &retiled, NULL, error);
        if (status == LK_OK && retiled.vertex_count <= contour_target &&
            retiled.vertex_count > result->mesh.vertex_count && retiled.triangle_count > 0) {
            lk_mesh_free(&result->mesh);
            result->mesh = retiled;
            lk_slices_free(&run.simplified);
            run.simplified = simplified;
            info.target_reached = 1;
            run.info = info;
        } else {
            lk_mesh_free(&retiled);
            lk_slices_free(&simplified);
        }
    }
    if (status == LK_OK && result->mesh.triangle_count == 0)
        status = lk_error_set(error, LK_ERR_INVALID,
                              "no contour spans two neighbouring slices (%zu slices along %c): use more slices",
                              run.slices.slice_count, "xyz"[run.slices.axis - 1]);
    if (status == LK_OK && refine && target > result->mesh.vertex_count) {
        lk_surface_index *input_index = NULL;
        status = lk_surface_index_build(mesh, &input_index, error);
        if (status == LK_OK)
            status = refine_between_planes(mesh, input_index, &result->mesh, target - result->mesh.vertex_count,
                                           run.slices.diagonal, error);
        lk_surface_index_free(input_index);
    }
    if (status == LK_OK) {
        result->vertex_map = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
        if (!result->vertex_map)
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the vertex map");
        else
            for (size_t v = 0; v < mesh->vertex_count; v++) result->vertex_map[v] = UINT32_MAX;
    }
    if (status == LK_OK) {
        double in_plane = run.info.error, sampling = run.slices.sampling_error;
        result->error = sqrt(in_plane * in_plane + sampling * sampling);
        result->target_reached = run.info.target_reached;
    } else {
        lk_mesh_free(&result->mesh);
    }
    wavelet_run_free(&run);
    return status;
}

lk_status lk__simplify_wavelet(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                               lk_progress_fn progress, void *progress_user, lk_error *error)
{
    lk_mesh closed;
    size_t hole_count = 0;
    lk_status status = close_holes(mesh, &closed, &hole_count, error);
    if (status != LK_OK) return status;
    status = simplify_wavelet(hole_count ? &closed : mesh, options, result, progress, progress_user, error);
    lk_mesh_free(&closed);
    return status;
}
