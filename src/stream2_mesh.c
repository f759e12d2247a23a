/* SPDX-License-Identifier: MIT */
/* The mesh a version-2 stream decoder builds (stream2_internal.h): vertices
 * with quantised positions, triangles, and per vertex a linked list of its
 * corners, so a vertex split touches only the triangles around one vertex.
 * The encoder runs the same code, so vertex and triangle numbers, fans,
 * contexts and predictions agree bit for bit. */
#include "stream2_internal.h"

#include <stdlib.h>
#include <string.h>

void lk__lks2_mesh_free(lks2_mesh *mesh)
{
    free(mesh->quantised);
    free(mesh->head);
    free(mesh->corners);
    free(mesh->next_corner);
    memset(mesh, 0, sizeof *mesh);
}

lk_status lk__lks2_mesh_reserve(lks2_mesh *mesh, size_t vertex_count, size_t triangle_count, lk_error *error)
{
    if (vertex_count > mesh->vertex_capacity) {
        int32_t *quantised = lk__realloc_array(mesh->quantised, vertex_count, 3 * sizeof(int32_t));
        if (quantised) mesh->quantised = quantised;
        uint32_t *head = lk__realloc_array(mesh->head, vertex_count, sizeof(uint32_t));
        if (head) mesh->head = head;
        if (!quantised || !head)
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream vertices", vertex_count);
        mesh->vertex_capacity = vertex_count;
    }
    if (triangle_count > mesh->triangle_capacity) {
        uint32_t *corners = lk__realloc_array(mesh->corners, triangle_count, 3 * sizeof(uint32_t));
        if (corners) mesh->corners = corners;
        uint32_t *next = lk__realloc_array(mesh->next_corner, triangle_count, 3 * sizeof(uint32_t));
        if (next) mesh->next_corner = next;
        if (!corners || !next)
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream triangles", triangle_count);
        mesh->triangle_capacity = triangle_count;
    }
    return LK_OK;
}

uint32_t lk__lks2_add_vertex(lks2_mesh *mesh, const int32_t position[3])
{
    uint32_t v = (uint32_t)mesh->vertex_count++;
    memcpy(mesh->quantised + 3 * (size_t)v, position, 3 * sizeof(int32_t));
    mesh->head[v] = LKS_NONE;
    return v;
}

void lk__lks2_add_triangle(lks2_mesh *mesh, uint32_t a, uint32_t b, uint32_t c)
{
    size_t t = mesh->triangle_count++;
    uint32_t vertices[3] = {a, b, c};
    for (int k = 0; k < 3; k++) {
        uint32_t corner = (uint32_t)(3 * t + (size_t)k);
        mesh->corners[corner] = vertices[k];
        mesh->next_corner[corner] = mesh->head[vertices[k]];
        mesh->head[vertices[k]] = corner;
    }
}

size_t lk__lks2_vertex_triangles(const lks2_mesh *mesh, uint32_t v, uint32_t *out, size_t capacity)
{
    size_t count = 0;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        if (count < capacity) {
            /* Insertion keeps the list sorted: fans are short. */
            uint32_t t = corner / 3;
            size_t i = count;
            while (i > 0 && out[i - 1] > t) {
                out[i] = out[i - 1];
                i--;
            }
            out[i] = t;
        }
        count++;
    }
    return count;
}

void lk__lks2_move_corner(lks2_mesh *mesh, uint32_t t, uint32_t v, uint32_t to)
{
    uint32_t *link = &mesh->head[v];
    while (*link != LKS_NONE && *link / 3 != t) link = &mesh->next_corner[*link];
    if (*link == LKS_NONE) return;
    uint32_t corner = *link;
    *link = mesh->next_corner[corner];
    mesh->corners[corner] = to;
    mesh->next_corner[corner] = mesh->head[to];
    mesh->head[to] = corner;
}

void lk__lks2_predict(const lks2_mesh *mesh, uint32_t v, const int32_t fallback[3], int32_t out[3])
{
    int64_t sum[3] = {0, 0, 0};
    int64_t count = 0;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        uint32_t base = corner - corner % 3;
        for (uint32_t k = 0; k < 3; k++) {
            uint32_t other = mesh->corners[base + k];
            if (other == v) continue;
            for (int axis = 0; axis < 3; axis++) sum[axis] += mesh->quantised[3 * (size_t)other + (size_t)axis];
            count++;
        }
    }
    for (int axis = 0; axis < 3; axis++)
        out[axis] = count ? (int32_t)((2 * sum[axis] + count) / (2 * count)) : fallback[axis];
}

void lk__lks2_models_init(lks2_models *models)
{
    lks2_uint_model_init(&models->gap);
    lks2_probs_init(models->move, LKS2_MOVE_CONTEXTS);
    lks2_probs_init(models->predicted_ok, 2);
    lks2_probs_init(models->kind, 4);
    lks2_uint_model_init(&models->escape_count);
    models->orientation = LKS2_PROB_INIT;
    for (int axis = 0; axis < 3; axis++) lks2_uint_model_init(&models->residual[axis]);
    lks2_uint_model_init(&models->batch_size);
    for (int c = 0; c < 3; c++) lks2_uint_model_init(&models->corner[c]);
}

/* True when triangles s and t share a vertex other than v: an edge through v. */
static bool share_edge(const lks2_mesh *mesh, uint32_t v, uint32_t s, uint32_t t)
{
    for (int i = 0; i < 3; i++) {
        uint32_t a = mesh->corners[3 * (size_t)s + (size_t)i];
        if (a == v) continue;
        for (int k = 0; k < 3; k++)
            if (mesh->corners[3 * (size_t)t + (size_t)k] == a) return true;
    }
    return false;
}

unsigned lk__lks2_move_context(const lks2_mesh *mesh, uint32_t v, const uint32_t *fan, const unsigned char *moved,
                               size_t index)
{
    if (index == 0) return LKS2_MOVE_CONTEXTS - 1;
    unsigned moving = 0, staying = 0;
    for (size_t j = 0; j < index; j++) {
        if (!share_edge(mesh, v, fan[j], fan[index])) continue;
        if (moved[j])
            moving += moving < 2;
        else
            staying += staying < 2;
    }
    return 3 * moving + staying;
}

/* The vertex of triangle t after v in drawing order. */
static uint32_t after(const lks2_mesh *mesh, uint32_t t, uint32_t v)
{
    const uint32_t *c = mesh->corners + 3 * (size_t)t;
    return c[0] == v ? c[1] : c[1] == v ? c[2] : c[0];
}

size_t lk__lks2_predict_restored(const lks2_mesh *mesh, uint32_t p, uint32_t q, const uint32_t *fan,
                                 const unsigned char *moved, size_t fan_size, uint32_t *out, size_t capacity)
{
    size_t count = 0;
    for (size_t s = 0; s < fan_size; s++) {
        if (moved[s]) continue;
        const uint32_t *staying = mesh->corners + 3 * (size_t)fan[s];
        for (int i = 0; i < 3; i++) {
            uint32_t w = staying[i];
            if (w == p) continue;
            bool bordered = false;
            for (size_t m = 0; m < fan_size && !bordered; m++) {
                if (!moved[m]) continue;
                const uint32_t *moving = mesh->corners + 3 * (size_t)fan[m];
                bordered = moving[0] == w || moving[1] == w || moving[2] == w;
            }
            if (!bordered) continue;
            if (count < capacity) {
                uint32_t *triangle = out + 3 * count;
                /* The new triangle crosses edge (p, w) the other way round. */
                if (after(mesh, fan[s], p) == w)
                    triangle[0] = p, triangle[1] = q, triangle[2] = w;
                else
                    triangle[0] = p, triangle[1] = w, triangle[2] = q;
            }
            count++;
        }
    }
    return count;
}

void lk__lks2_exclude(const lks2_mesh *mesh, uint32_t v, uint32_t *stamp, uint32_t serial)
{
    stamp[v] = serial;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        uint32_t base = corner - corner % 3;
        for (uint32_t k = 0; k < 3; k++) stamp[mesh->corners[base + k]] = serial;
    }
}
