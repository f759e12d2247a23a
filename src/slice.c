/* SPDX-License-Identifier: MIT */
/* Planar sampling of a closed surface into ordered contours (the paper's
 * "equivalent contours", section 3.1).
 *
 * The paper projects every vertex to its nearest slice and joins the
 * projections "in order"; that order is not defined for a general mesh, so
 * lodkit takes the exact intersection of each plane with the mesh instead:
 * one point per mesh edge crossing the plane, chained through the triangles.
 * The planes sit at the centres of equal cells of the bounding box, so the
 * sampling error is half a spacing, as in the paper's Table 3.
 *
 * Robustness: a vertex is "above" plane k when its coordinate is >= the
 * plane's (a symbolic offset of the plane downwards by an infinitesimal).
 * Each vertex then has one side per plane, every edge crosses or does not,
 * and in a closed 2-manifold every crossed triangle has exactly two crossed
 * edges: contours always close. An edge whose upper end lies on the plane
 * gives that vertex exactly, so the repeated points of a contour passing
 * through a vertex are bitwise equal and merged.
 *
 * Orientation: walking a counter-clockwise (outward) triangle's corners,
 * the crossed edge going from above to below comes first and the one going
 * from below to above second; the segment between their points runs along
 * axis x outward normal, so outer contours turn counter-clockwise seen from
 * +axis and holes clockwise. The shared edge is the second one of a
 * triangle and the first one of its neighbour, which gives the chaining. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NO_EDGE UINT32_MAX

void lk_slices_init(lk_slices *slices) { memset(slices, 0, sizeof *slices); }

void lk_slices_free(lk_slices *slices)
{
    if (!slices) return;
    free(slices->contours);
    free(slices->points);
    lk_slices_init(slices);
}

double lk_slices_plane(const lk_slices *slices, size_t k)
{
    return slices->origin + ((double)k + 0.5) * slices->spacing;
}

static double plane_at(double origin, double spacing, size_t k) { return origin + ((double)k + 0.5) * spacing; }

/* Checks that every edge has two triangles using it in opposite directions. */
static lk_status check_closed(const lk_mesh *mesh, const lk_edge_adjacency *edges, lk_error *error)
{
    size_t boundary = 0, nonmanifold = 0, flipped = 0;
    size_t first_boundary = SIZE_MAX, first_nonmanifold = SIZE_MAX, first_flipped = SIZE_MAX;
    for (size_t e = 0; e < edges->edge_count; e++) {
        uint32_t uses = edges->offsets[e + 1] - edges->offsets[e];
        if (uses == 1) {
            if (!boundary++) first_boundary = e;
        } else if (uses > 2) {
            if (!nonmanifold++) first_nonmanifold = e;
        } else {
            uint32_t a = edges->vertices[2 * e];
            int forward = 0;
            for (uint32_t k = edges->offsets[e]; k < edges->offsets[e + 1]; k++) {
                uint32_t t = edges->triangles[k];
                for (int corner = 0; corner < 3; corner++)
                    if (mesh->indices[3 * t + corner] == a && edges->triangle_edges[3 * t + corner] == e) forward++;
            }
            if (forward != 1 && !flipped++) first_flipped = e;
        }
    }
    if (boundary)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "wavelet slicing needs a closed surface: %zu boundary edges (open mesh; the first joins "
                            "vertices %u and %u); close the holes first",
                            boundary, edges->vertices[2 * first_boundary], edges->vertices[2 * first_boundary + 1]);
    if (nonmanifold)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "wavelet slicing needs a 2-manifold: %zu edges have more than two triangles (the first "
                            "joins vertices %u and %u)",
                            nonmanifold, edges->vertices[2 * first_nonmanifold],
                            edges->vertices[2 * first_nonmanifold + 1]);
    if (flipped)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "wavelet slicing needs consistently oriented triangles: %zu edges are used twice in the "
                            "same direction (the first joins vertices %u and %u)",
                            flipped, edges->vertices[2 * first_flipped], edges->vertices[2 * first_flipped + 1]);
    return LK_OK;
}

typedef struct growable {
    void *data;
    size_t count, capacity, element;
} growable;

static int grow(growable *g, size_t extra)
{
    if (g->count + extra <= g->capacity) return 1;
    size_t capacity = g->capacity ? g->capacity : 256;
    while (capacity < g->count + extra) capacity *= 2;
    void *data = lk__realloc_array(g->data, capacity, g->element);
    if (!data) return 0;
    g->data = data;
    g->capacity = capacity;
    return 1;
}

/* Number of planes at or below z: the index (plus one) of the slab holding
 * z, 0 below plane 0 up to slice_count above the last plane. A coordinate
 * equal to a plane's is above it, as in the side test of lk_mesh_slice. */
static uint32_t slab_of(double z, double origin, double spacing, size_t slice_count)
{
    double estimate = floor((z - origin) / spacing - 0.5) + 1;
    if (!(estimate > 0)) estimate = 0;
    size_t k = estimate > (double)slice_count ? slice_count : (size_t)estimate;
    while (k > 0 && plane_at(origin, spacing, k - 1) > z) k--;
    while (k < slice_count && plane_at(origin, spacing, k) <= z) k++;
    return (uint32_t)k;
}

static size_t piece_root(size_t *parent, size_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

/* Sets every contour's `below` and `above` piece ids. The surface between
 * two neighbouring planes (a slab) falls into connected pieces; contours
 * touching one piece are joined by the surface there, which is what the
 * tiling must reproduce (the overlap of their areas is only a guess: a thin
 * slanted limb's contours need not overlap, and a torus's bottom joins its
 * outer contour to its hole). The part of triangle t inside slab j is
 * convex, hence connected; two such parts of triangles sharing an edge are
 * connected when the edge reaches into the slab. A union-find over these
 * (triangle, slab) parts gives the pieces. Cost: O(T + crossings). */
static lk_status label_pieces(const lk_mesh *mesh, const lk_edge_adjacency *edges, unsigned axis, double origin,
                              double spacing, size_t slice_count, lk_contour *contours, size_t contour_count,
                              const uint32_t *starts, lk_error *error)
{
    size_t vertex_count = mesh->vertex_count, triangle_count = mesh->triangle_count;
    uint32_t *vertex_slab = lk__malloc_array(vertex_count ? vertex_count : 1, sizeof(uint32_t));
    uint32_t *lowest = lk__malloc_array(triangle_count, sizeof(uint32_t));
    size_t *first_part = lk__malloc_array(triangle_count + 1, sizeof(size_t));
    size_t *parent = NULL;
    uint32_t *label = NULL;
    lk_status status = LK_OK;
    if (!vertex_slab || !lowest || !first_part) goto nomem;
    for (size_t v = 0; v < vertex_count; v++)
        vertex_slab[v] = slab_of(mesh->positions[3 * v + axis], origin, spacing, slice_count);
    first_part[0] = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *tri = mesh->indices + 3 * t;
        uint32_t lo = vertex_slab[tri[0]], hi = lo;
        for (int c = 1; c < 3; c++) {
            uint32_t s = vertex_slab[tri[c]];
            if (s < lo) lo = s;
            if (s > hi) hi = s;
        }
        lowest[t] = lo;
        first_part[t + 1] = first_part[t] + (hi - lo + 1);
    }
    size_t part_count = first_part[triangle_count];
    parent = lk__malloc_array(part_count, sizeof(size_t));
    label = lk__calloc_array(part_count, sizeof(uint32_t));
    if (!parent || !label) goto nomem;
    for (size_t p = 0; p < part_count; p++) parent[p] = p;
    for (size_t e = 0; e < edges->edge_count; e++) {
        if (edges->offsets[e + 1] - edges->offsets[e] != 2) continue; /* closed input: always 2 */
        uint32_t t0 = edges->triangles[edges->offsets[e]], t1 = edges->triangles[edges->offsets[e] + 1];
        uint32_t s0 = vertex_slab[edges->vertices[2 * e]], s1 = vertex_slab[edges->vertices[2 * e + 1]];
        uint32_t lo = s0 < s1 ? s0 : s1, hi = s0 < s1 ? s1 : s0;
        for (uint32_t s = lo; s <= hi; s++) {
            size_t r0 = piece_root(parent, first_part[t0] + (s - lowest[t0]));
            size_t r1 = piece_root(parent, first_part[t1] + (s - lowest[t1]));
            if (r0 != r1) parent[r0 > r1 ? r0 : r1] = r0 < r1 ? r0 : r1;
        }
    }
    /* Contour on plane k: its start triangle crosses the plane, so it has
     * parts in slab k (below the plane) and k + 1 (above). */
    uint32_t next_label = 1;
    for (size_t c = 0; c < contour_count; c++) {
        uint32_t t = starts[c], k = contours[c].slice;
        for (int side = 0; side < 2; side++) {
            uint32_t slab = k + (uint32_t)side;
            size_t root = piece_root(parent, first_part[t] + (slab - lowest[t]));
            if (!label[root]) {
                if (next_label == UINT32_MAX) {
                    status = lk_error_set(error, LK_ERR_LIMIT, "too many surface pieces between the planes");
                    goto done;
                }
                label[root] = next_label++;
            }
            if (side == 0)
                contours[c].below = label[root];
            else
                contours[c].above = label[root];
        }
    }
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the surface pieces between the planes");
done:
    free(vertex_slab);
    free(lowest);
    free(first_part);
    free(parent);
    free(label);
    return status;
}

lk_status lk_mesh_slice(const lk_mesh *mesh, lk_axis axis, size_t slice_count, lk_slices *out, lk_progress_fn progress,
                        void *progress_user, lk_error *error)
{
    if (!mesh || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_mesh_slice: NULL argument");
    lk_slices_init(out);
    if (axis < LK_AXIS_AUTO || axis > LK_AXIS_Z)
        return lk_error_set(error, LK_ERR_INVALID, "unknown slicing axis %d", (int)axis);
    if (slice_count < 2 || slice_count > 1000000)
        return lk_error_set(error, LK_ERR_INVALID, "slice count must be in 2..1000000, got %zu", slice_count);
    lk_status status = lk_mesh_validate(mesh, error);
    if (status != LK_OK) return status;
    if (mesh->triangle_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "cannot slice a point set (%zu points, no triangles)",
                            mesh->vertex_count);
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *tri = mesh->indices + 3 * t;
        if (tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0])
            return lk_error_set(error, LK_ERR_UNSUPPORTED,
                                "triangle %zu is degenerate (repeated vertex %u): remove degenerate triangles first", t,
                                tri[0] == tri[1] ? tri[0] : tri[2]);
    }
    /* Bounds over the vertices the triangles use. */
    double low[3] = {INFINITY, INFINITY, INFINITY}, high[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < 3 * mesh->triangle_count; i++) {
        const float *p = mesh->positions + 3 * (size_t)mesh->indices[i];
        for (int a = 0; a < 3; a++) {
            if (p[a] < low[a]) low[a] = p[a];
            if (p[a] > high[a]) high[a] = p[a];
        }
    }
    double extent[3] = {high[0] - low[0], high[1] - low[1], high[2] - low[2]};
    double diagonal = sqrt(extent[0] * extent[0] + extent[1] * extent[1] + extent[2] * extent[2]);
    unsigned a;
    if (axis == LK_AXIS_AUTO) {
        /* The shortest side; ties go to z, then y (the paper's choice for
         * both its models was z). */
        a = 2;
        if (extent[1] < extent[a]) a = 1;
        if (extent[0] < extent[a]) a = 0;
    } else {
        a = (unsigned)axis - 1;
    }
    static const char axis_names[3] = {'x', 'y', 'z'};
    if (!(diagonal > 0))
        return lk_error_set(error, LK_ERR_INVALID,
                            "every vertex is at one point (zero bounding box): there is no surface to slice");
    if (!(extent[a] > 0) && axis == LK_AXIS_AUTO)
        /* Auto picks the shortest side: zero means the whole mesh lies in
         * one plane, so it cannot enclose a volume along any axis. */
        return lk_error_set(error, LK_ERR_INVALID,
                            "the mesh is flat along %c (the shortest side has zero extent): it lies in one plane "
                            "and encloses no volume, so no slices can cut it",
                            axis_names[a]);
    if (!(extent[a] > 0))
        return lk_error_set(error, LK_ERR_INVALID,
                            "the mesh is flat along %c (zero bounding-box extent): no slices can cut it; choose "
                            "another axis",
                            axis_names[a]);

    lk_edge_adjacency edges;
    status = lk_edge_adjacency_build(mesh, &edges, error);
    if (status != LK_OK) return status;
    status = check_closed(mesh, &edges, error);
    if (status != LK_OK) {
        lk_edge_adjacency_free(&edges);
        return status;
    }

    out->axis = (lk_axis)(a + 1);
    out->u_axis = (a + 1) % 3;
    out->v_axis = (a + 2) % 3;
    out->slice_count = slice_count;
    out->origin = low[a];
    out->spacing = extent[a] / (double)slice_count;
    out->sampling_error = 0.5 * out->spacing;
    out->diagonal = diagonal;
    const double origin = out->origin, spacing = out->spacing;

    /* Triangles per slice (compressed rows). */
    size_t *slice_offsets = lk__calloc_array(slice_count + 1, sizeof(size_t));
    uint32_t *next_edge = lk__malloc_array(edges.edge_count, sizeof(uint32_t));
    unsigned char *visited = lk__calloc_array(edges.edge_count, 1);
    uint32_t *slice_triangles = NULL;
    growable contours = {NULL, 0, 0, sizeof(lk_contour)};
    growable points = {NULL, 0, 0, 2 * sizeof(double)};
    growable starts = {NULL, 0, 0, sizeof(uint32_t)}; /* a crossed triangle of each contour */
    if (!slice_offsets || !next_edge || !visited) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate slicing tables");
        goto done;
    }
    for (size_t e = 0; e < edges.edge_count; e++) next_edge[e] = NO_EDGE;
    /* The planes crossing triangle t are k_first..k_last: lo < plane <= hi.
     * The estimate from the division is corrected with exact comparisons so
     * that it agrees with the per-vertex side test below. */
    for (int pass = 0; pass < 2; pass++) {
        size_t *fill = NULL;
        if (pass == 1) {
            for (size_t k = 0; k < slice_count; k++) slice_offsets[k + 1] += slice_offsets[k];
            slice_triangles = lk__malloc_array(slice_offsets[slice_count], sizeof(uint32_t));
            fill = lk__malloc_array(slice_count, sizeof(size_t));
            if (!slice_triangles || !fill) {
                free(fill);
                status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu slice crossings",
                                      slice_offsets[slice_count]);
                goto done;
            }
            memcpy(fill, slice_offsets, slice_count * sizeof(size_t));
        }
        for (size_t t = 0; t < mesh->triangle_count; t++) {
            double lo = INFINITY, hi = -INFINITY;
            for (int c = 0; c < 3; c++) {
                double z = mesh->positions[3 * (size_t)mesh->indices[3 * t + c] + a];
                if (z < lo) lo = z;
                if (z > hi) hi = z;
            }
            double first_estimate = ceil((lo - origin) / spacing - 0.5);
            if (first_estimate < 0) first_estimate = 0;
            size_t k = first_estimate > (double)slice_count ? slice_count : (size_t)first_estimate;
            while (k > 0 && plane_at(origin, spacing, k - 1) > lo) k--;
            while (k < slice_count && plane_at(origin, spacing, k) <= lo) k++;
            for (; k < slice_count && plane_at(origin, spacing, k) <= hi; k++) {
                if (pass == 0)
                    slice_offsets[k + 1]++;
                else
                    slice_triangles[fill[k]++] = (uint32_t)t;
            }
        }
        free(fill);
    }

    for (size_t k = 0; k < slice_count; k++) {
        if (progress && (k & 15) == 0 && progress(progress_user, 0.25 * (double)k / (double)slice_count, "slicing")) {
            status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
            goto done;
        }
        double plane = plane_at(origin, spacing, k);
        size_t begin = slice_offsets[k], end = slice_offsets[k + 1];
        /* Link each triangle's first crossed edge (above -> below) to its
         * second (below -> above). */
        for (size_t i = begin; i < end; i++) {
            uint32_t t = slice_triangles[i];
            int above[3];
            for (int c = 0; c < 3; c++) above[c] = mesh->positions[3 * (size_t)mesh->indices[3 * t + c] + a] >= plane;
            uint32_t down = NO_EDGE, up = NO_EDGE;
            for (int c = 0; c < 3; c++) {
                int n = (c + 1) % 3;
                if (above[c] && !above[n]) down = edges.triangle_edges[3 * t + c];
                if (!above[c] && above[n]) up = edges.triangle_edges[3 * t + c];
            }
            if (down == NO_EDGE || up == NO_EDGE) continue; /* cannot happen: the range test agrees */
            next_edge[down] = up;
        }
        for (size_t i = begin; i < end; i++) {
            uint32_t t = slice_triangles[i];
            uint32_t start = NO_EDGE;
            for (int c = 0; c < 3 && start == NO_EDGE; c++) {
                uint32_t e = edges.triangle_edges[3 * t + c];
                if (next_edge[e] != NO_EDGE && !visited[e]) start = e;
            }
            if (start == NO_EDGE) continue;
            size_t first_point = points.count;
            uint32_t e = start;
            int closed = 0;
            while (!visited[e]) {
                visited[e] = 1;
                /* The crossing point: the vertex itself when the upper end
                 * lies on the plane, else the interpolation. */
                uint32_t v0 = edges.vertices[2 * e], v1 = edges.vertices[2 * e + 1];
                const float *p0 = mesh->positions + 3 * (size_t)v0, *p1 = mesh->positions + 3 * (size_t)v1;
                if (p0[a] >= plane) {
                    const float *swap = p0;
                    p0 = p1;
                    p1 = swap;
                }
                double point[2];
                if ((double)p1[a] == plane) {
                    point[0] = p1[out->u_axis];
                    point[1] = p1[out->v_axis];
                } else {
                    double s = (plane - p0[a]) / ((double)p1[a] - p0[a]);
                    point[0] = p0[out->u_axis] + s * ((double)p1[out->u_axis] - p0[out->u_axis]);
                    point[1] = p0[out->v_axis] + s * ((double)p1[out->v_axis] - p0[out->v_axis]);
                }
                double *last = points.count > first_point ? (double *)points.data + 2 * (points.count - 1) : NULL;
                if (!last || last[0] != point[0] || last[1] != point[1]) {
                    if (!grow(&points, 1)) {
                        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate contour points");
                        goto done;
                    }
                    double *slot = (double *)points.data + 2 * points.count++;
                    slot[0] = point[0];
                    slot[1] = point[1];
                }
                uint32_t next = next_edge[e];
                if (next == NO_EDGE) break;
                e = next;
                if (e == start) closed = 1;
            }
            if (!closed) {
                status = lk_error_set(error, LK_ERR_INVALID, "internal error: contour on slice %zu does not close", k);
                goto done;
            }
            double *base = (double *)points.data + 2 * first_point;
            size_t count = points.count - first_point;
            while (count >= 2 && base[0] == base[2 * (count - 1)] && base[1] == base[2 * (count - 1) + 1]) count--;
            if (count < 3) { /* a point (a vertex touching the plane) or a segment */
                points.count = first_point;
                continue;
            }
            points.count = first_point + count;
            if (points.count > UINT32_MAX || !grow(&contours, 1) || !grow(&starts, 1)) {
                status = lk_error_set(error, points.count > UINT32_MAX ? LK_ERR_LIMIT : LK_ERR_NOMEM,
                                      "too many contour points (%zu)", points.count);
                goto done;
            }
            ((uint32_t *)starts.data)[starts.count++] = t;
            lk_contour *contour = (lk_contour *)contours.data + contours.count++;
            memset(contour, 0, sizeof *contour);
            contour->slice = (uint32_t)k;
            contour->first = (uint32_t)first_point;
            contour->count = (uint32_t)count;
            contour->level = 0;
            double area = 0;
            for (size_t j = 1; j + 1 < count; j++) {
                const double *p = base + 2 * j, *q = base + 2 * (j + 1);
                area += (p[0] - base[0]) * (q[1] - base[1]) - (p[1] - base[1]) * (q[0] - base[0]);
            }
            contour->area = 0.5 * area;
        }
        for (size_t i = begin; i < end; i++) {
            uint32_t t = slice_triangles[i];
            for (int c = 0; c < 3; c++) {
                uint32_t e = edges.triangle_edges[3 * t + c];
                next_edge[e] = NO_EDGE;
                visited[e] = 0;
            }
        }
    }
    if (progress && progress(progress_user, 0.25, "slicing")) {
        status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
        goto done;
    }
    status = label_pieces(mesh, &edges, a, origin, spacing, slice_count, (lk_contour *)contours.data, contours.count,
                          (const uint32_t *)starts.data, error);
    if (status != LK_OK) goto done;
    out->contour_count = contours.count;
    out->contours = contours.data;
    out->point_count = points.count;
    out->points = points.data;
    contours.data = points.data = NULL;
    if (!out->contours) out->contours = lk__malloc_array(1, sizeof(lk_contour));
    if (!out->points) out->points = lk__malloc_array(2, sizeof(double));
    if (!out->contours || !out->points) status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate contours");
done:
    free(contours.data);
    free(points.data);
    free(starts.data);
    free(slice_offsets);
    free(slice_triangles);
    free(next_edge);
    free(visited);
    lk_edge_adjacency_free(&edges);
    if (status != LK_OK) lk_slices_free(out);
    return status;
}
