/* SPDX-License-Identifier: MIT */
/* The server's reference-counted bytes (a response may still be sending
 * bytes the cache has evicted) and its memory cache: gzip results, the
 * index and point buffers share one byte budget, least recently used
 * first out. */
#include "serve_shared.h"

#include <stdlib.h>
#include <string.h>

/* ---- reference-counted bytes and the memory cache ---------------------- */

/* Takes ownership of data (malloc'ed). One reference for the caller. */
blob *lk__serve_blob_wrap(unsigned char *data, size_t size)
{
    blob *b = malloc(sizeof *b);
    if (!b) return NULL;
    atomic_init(&b->references, 1);
    b->size = size;
    b->data = data;
    return b;
}

void lk__serve_blob_retain(blob *b) { atomic_fetch_add(&b->references, 1); }

void lk__serve_blob_release(void *pointer)
{
    blob *b = pointer;
    if (b && atomic_fetch_sub(&b->references, 1) == 1) {
        free(b->data);
        free(b);
    }
}

/* A new reference to the cached value, or NULL. */
blob *lk__serve_cache_get(memory_cache *cache, const char *key)
{
    blob *found = NULL;
    pthread_mutex_lock(&cache->lock);
    for (size_t i = 0; i < cache->count; i++)
        if (strcmp(cache->entries[i].key, key) == 0) {
            found = cache->entries[i].value;
            cache->entries[i].last_used = ++cache->clock;
            lk__serve_blob_retain(found);
            break;
        }
    pthread_mutex_unlock(&cache->lock);
    return found;
}

static void cache_remove_at(memory_cache *cache, size_t i)
{
    cache->bytes -= cache->entries[i].value->size;
    lk__serve_blob_release(cache->entries[i].value);
    free(cache->entries[i].key);
    cache->entries[i] = cache->entries[--cache->count];
}

/* Stores value under key (the cache takes its own reference); values
 * larger than half the budget are not kept. Failures only mean no caching. */
void lk__serve_cache_put(memory_cache *cache, const char *key, blob *value)
{
    if (value->size > cache->budget / 2) return;
    pthread_mutex_lock(&cache->lock);
    for (size_t i = 0; i < cache->count; i++)
        if (strcmp(cache->entries[i].key, key) == 0) {
            cache_remove_at(cache, i);
            break;
        }
    while (cache->count && cache->bytes + value->size > cache->budget) {
        size_t oldest = 0;
        for (size_t i = 1; i < cache->count; i++)
            if (cache->entries[i].last_used < cache->entries[oldest].last_used) oldest = i;
        cache_remove_at(cache, oldest);
    }
    if (cache->count == cache->capacity) {
        size_t capacity = cache->capacity ? 2 * cache->capacity : 16;
        cache_entry *grown = lk__realloc_array(cache->entries, capacity, sizeof *grown);
        if (!grown) goto done;
        cache->entries = grown;
        cache->capacity = capacity;
    }
    char *key_copy = strdup(key);
    if (!key_copy) goto done;
    lk__serve_blob_retain(value);
    cache->entries[cache->count++] = (cache_entry){key_copy, value, ++cache->clock};
    cache->bytes += value->size;
done:
    pthread_mutex_unlock(&cache->lock);
}

void lk__serve_cache_free(memory_cache *cache)
{
    while (cache->count) cache_remove_at(cache, cache->count - 1);
    free(cache->entries);
    pthread_mutex_destroy(&cache->lock);
}
