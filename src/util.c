/* SPDX-License-Identifier: MIT */
/* Shared helpers: files, number parsing, buffers (errors and checked allocation: status.c). */
#define _GNU_SOURCE /* fopencookie: the atomic outputs keep the errno of a failed buffered write */
#include "internal.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

const char *lk_version(void) { return LK_VERSION_STRING; }

/* ---- allocation -------------------------------------------------------- */

/* Huge page size on x86-64 and arm64 Linux (4 KiB base pages). */
#define HUGE_PAGE_BYTES ((size_t)2 << 20)
#define CACHE_LINE_BYTES ((size_t)64)

void *lk__alloc_random_access(size_t count, size_t size, bool zero)
{
    if (size && count > SIZE_MAX / size) return NULL;
    size_t bytes = count * size;
    if (bytes > SIZE_MAX - HUGE_PAGE_BYTES) return NULL;
    /* Smaller arrays: a few 4 KiB pages cover them anyway. */
    size_t alignment = bytes >= 2 * HUGE_PAGE_BYTES ? HUGE_PAGE_BYTES : CACHE_LINE_BYTES;
    size_t rounded = (bytes + alignment - 1) / alignment * alignment;
    void *memory = aligned_alloc(alignment, rounded ? rounded : alignment);
    if (!memory) return NULL;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (alignment == HUGE_PAGE_BYTES) madvise(memory, rounded, MADV_HUGEPAGE); /* advice: failure is harmless */
#endif
    if (zero) memset(memory, 0, bytes);
    return memory;
}

bool lk__buffer_reserve(lk__buffer *buffer, size_t extra)
{
    if (extra > SIZE_MAX - buffer->size) return false;
    size_t need = buffer->size + extra;
    if (need <= buffer->capacity) return true;
    size_t capacity = buffer->capacity ? buffer->capacity : 256;
    while (capacity < need) {
        if (capacity > SIZE_MAX / 2) {
            capacity = need;
            break;
        }
        capacity *= 2;
    }
    unsigned char *data = realloc(buffer->data, capacity);
    if (!data) return false;
    buffer->data = data;
    buffer->capacity = capacity;
    return true;
}

bool lk__buffer_append(lk__buffer *buffer, const void *bytes, size_t size)
{
    if (!lk__buffer_reserve(buffer, size)) return false;
    if (size) memcpy(buffer->data + buffer->size, bytes, size);
    buffer->size += size;
    return true;
}

void lk__buffer_free(lk__buffer *buffer)
{
    free(buffer->data);
    buffer->data = NULL;
    buffer->size = buffer->capacity = 0;
}

void *lk__buffer_take(lk__buffer *buffer)
{
    unsigned char *data = buffer->data;
    unsigned char *trimmed = buffer->size ? realloc(data, buffer->size) : NULL;
    if (trimmed) data = trimmed;
    buffer->data = NULL;
    buffer->size = buffer->capacity = 0;
    return data;
}

/* ---- memory budget of one read ------------------------------------------ */

bool lk__budget_charge(lk__budget *budget, size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return false;
    size_t bytes = count * size;
    if (bytes > lk__budget_room(budget)) return false;
    budget->held += bytes;
    return true;
}

void lk__budget_release(lk__budget *budget, size_t count, size_t size)
{
    size_t bytes = size && count > SIZE_MAX / size ? SIZE_MAX : count * size;
    budget->held = bytes < budget->held ? budget->held - bytes : 0;
}

bool lk__budget_charge_mesh(lk__budget *budget, size_t vertex_count, size_t triangle_count, unsigned flags)
{
    size_t floats_per_vertex = 3 + (flags & LK_ATTR_NORMALS ? 3 : 0) + (flags & LK_ATTR_TEXCOORDS ? 2 : 0) +
                               (flags & LK_ATTR_COLORS ? 4 : 0) + (flags & LK_ATTR_RADII ? 1 : 0);
    if (vertex_count > SIZE_MAX / sizeof(float) / floats_per_vertex) return false;
    if (!lk__budget_charge(budget, vertex_count, floats_per_vertex * sizeof(float))) return false;
    if (lk__budget_charge(budget, triangle_count, 3 * sizeof(uint32_t))) return true;
    lk__budget_release(budget, vertex_count, floats_per_vertex * sizeof(float));
    return false;
}

size_t lk__budget_grow_capacity(const lk__budget *budget, size_t capacity, size_t need, size_t size,
                                size_t first_capacity)
{
    if (need == 0) need = 1; /* an array is never empty: 0 means refused */
    if (need <= capacity) return capacity;
    size_t room = lk__budget_room(budget) / size; /* in elements */
    if (need - capacity > room) return 0;
    size_t doubled = capacity ? (capacity <= SIZE_MAX / 2 ? 2 * capacity : SIZE_MAX) : first_capacity;
    if (doubled < need) doubled = need;
    size_t spare = room - (need - capacity);
    size_t most = need + spare / 2;
    return doubled < most ? doubled : most;
}

lk_status lk__buffer_reserve_charged(lk__buffer *buffer, size_t extra, lk__budget *budget)
{
    if (extra > SIZE_MAX - buffer->size) return LK_ERR_LIMIT;
    size_t need = buffer->size + extra;
    if (need <= buffer->capacity) return LK_OK;
    size_t capacity = lk__budget_grow_capacity(budget, buffer->capacity, need, 1, 256);
    if (!capacity) return LK_ERR_LIMIT;
    unsigned char *data = realloc(buffer->data, capacity);
    if (!data) return LK_ERR_NOMEM;
    lk__budget_charge(budget, capacity - buffer->capacity, 1); /* fits: see lk__budget_grow_capacity */
    buffer->data = data;
    buffer->capacity = capacity;
    return LK_OK;
}

lk_status lk__buffer_append_charged(lk__buffer *buffer, const void *bytes, size_t size, lk__budget *budget)
{
    lk_status status = lk__buffer_reserve_charged(buffer, size, budget);
    if (status != LK_OK) return status;
    if (size) memcpy(buffer->data + buffer->size, bytes, size);
    buffer->size += size;
    return LK_OK;
}

void *lk__buffer_take_charged(lk__buffer *buffer, lk__budget *budget)
{
    size_t kept = buffer->size;
    lk__budget_release(budget, buffer->capacity - kept, 1);
    return lk__buffer_take(buffer);
}

void lk__buffer_free_charged(lk__buffer *buffer, lk__budget *budget)
{
    lk__budget_release(budget, buffer->capacity, 1);
    lk__buffer_free(buffer);
}

/* ---- files ------------------------------------------------------------- */

enum { LK__NAME_MAX = 255 }; /* bytes of one directory entry's name */


/* What a file that is not a regular file is, for messages. */
static const char *file_kind(mode_t mode)
{
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISSOCK(mode)) return "a socket";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISLNK(mode)) return "a symbolic link";
    if (S_ISREG(mode)) return "a regular file";
    return "a file of another kind";
}

static lk_status refuse_kind(const char *path, mode_t mode, lk_error *error)
{
    lk_error_set(error, LK_ERR_IO, "%s: is %s, not a regular file", path, file_kind(mode));
    errno = S_ISDIR(mode) ? EISDIR : S_ISLNK(mode) ? ELOOP : EPERM;
    return LK_ERR_IO;
}

static lk_status open_failed(const char *path, int saved, lk_error *error)
{
    lk_error_set(error, LK_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    errno = saved;
    return LK_ERR_IO;
}

/* Opens `path` below the directory `folder` one component at a time,
 * never following a symbolic link (fstatat + openat with O_NOFOLLOW: a
 * link swapped in between the two is refused by the open itself). */
static lk_status open_in_folder(const char *folder, const char *path, int flags, int *out, lk_error *error)
{
    if (path[0] == '/' || path[0] == '\0') {
        lk_error_set(error, LK_ERR_IO, "%s: not a relative path inside the folder", path);
        errno = EPERM;
        return LK_ERR_IO;
    }
    int directory = open(folder, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (directory < 0) {
        int saved = errno;
        lk_error_set(error, LK_ERR_IO, "%s: cannot open its folder %s: %s", path, folder, strerror(saved));
        errno = saved;
        return LK_ERR_IO;
    }
    const char *p = path;
    for (;;) {
        while (*p == '/') p++;
        size_t length = strcspn(p, "/");
        const char *rest = p + length;
        while (*rest == '/') rest++;
        bool last = *rest == '\0';
        int shown = (int)(p + length - path); /* the path up to this component, for messages */
        char name[LK__NAME_MAX + 1];
        if (length > LK__NAME_MAX) {
            close(directory);
            return open_failed(path, ENAMETOOLONG, error);
        }
        memcpy(name, p, length);
        name[length] = '\0';
        if (strcmp(name, "..") == 0) {
            close(directory);
            lk_error_set(error, LK_ERR_IO, "%s: \"..\" leaves the folder", path);
            errno = EPERM;
            return LK_ERR_IO;
        }
        struct stat info;
        if (fstatat(directory, name, &info, AT_SYMLINK_NOFOLLOW) != 0) {
            int saved = errno;
            close(directory);
            return open_failed(path, saved, error);
        }
        if (S_ISLNK(info.st_mode) && last) {
            close(directory);
            lk_error_set(error, LK_ERR_IO, "%s: is a symbolic link (not followed)", path);
            errno = ELOOP;
            return LK_ERR_IO;
        }
        if (!last && !S_ISDIR(info.st_mode)) {
            close(directory);
            lk_error_set(error, LK_ERR_IO, "%s: \"%.*s\" is %s%s", path, shown, path, file_kind(info.st_mode),
                         S_ISLNK(info.st_mode) ? " (not followed)" : ", not a directory");
            errno = S_ISLNK(info.st_mode) ? ELOOP : ENOTDIR;
            return LK_ERR_IO;
        }
        if (last && !S_ISREG(info.st_mode)) { /* refused before any open: a device's open may act */
            close(directory);
            return refuse_kind(path, info.st_mode, error);
        }
        int next = openat(directory, name, last ? flags | O_NOFOLLOW : O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
        int saved = errno;
        close(directory);
        if (next < 0) {
            if (saved == ELOOP) { /* a link swapped in since the fstatat */
                if (last)
                    lk_error_set(error, LK_ERR_IO, "%s: is a symbolic link (not followed)", path);
                else
                    lk_error_set(error, LK_ERR_IO, "%s: \"%.*s\" is a symbolic link (not followed)", path, shown, path);
                errno = ELOOP;
                return LK_ERR_IO;
            }
            return open_failed(path, saved, error);
        }
        if (last) {
            *out = next;
            return LK_OK;
        }
        directory = next;
        p = rest;
    }
}

lk_status lk__open_input(const char *folder, const char *path, int *fd, struct stat *info, lk_error *error)
{
    *fd = -1;
    /* O_NONBLOCK: opening a FIFO without a writer (or some devices) would
     * block in open() itself; O_NOCTTY: a terminal never becomes ours. */
    const int flags = O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY;
    int opened = -1;
    if (folder) {
        lk_status status = open_in_folder(folder, path, flags, &opened, error);
        if (status != LK_OK) return status;
    } else {
        /* Refuse what is not a regular file before opening it (opening a
         * device can act, e.g. a watchdog); the fstat below decides. */
        struct stat before;
        if (stat(path, &before) != 0) return open_failed(path, errno, error);
        if (!S_ISREG(before.st_mode)) return refuse_kind(path, before.st_mode, error);
        opened = open(path, flags);
        if (opened < 0) return open_failed(path, errno, error);
    }
    struct stat opened_info;
    if (fstat(opened, &opened_info) != 0) {
        int saved = errno;
        close(opened);
        return open_failed(path, saved, error);
    }
    if (!S_ISREG(opened_info.st_mode)) { /* swapped since the check */
        close(opened);
        return refuse_kind(path, opened_info.st_mode, error);
    }
    int status_flags = fcntl(opened, F_GETFL);
    if (status_flags < 0 || fcntl(opened, F_SETFL, status_flags & ~O_NONBLOCK) != 0) {
        int saved = errno;
        close(opened);
        return open_failed(path, saved, error);
    }
    *fd = opened;
    if (info) *info = opened_info;
    return LK_OK;
}

lk_status lk__read_prefix(int fd, const struct stat *info, const char *name, size_t length, void *out, lk_error *error)
{
    /* pread: the descriptor's offset does not matter. A file that changes
     * under the read (truncated, appended to, rewritten: its size or
     * modification time differ afterwards) is an error, never a mix of
     * versions or a short buffer taken for the whole file. */
    unsigned char *bytes = out;
    size_t done = 0;
    while (done < length) {
        ssize_t n = pread(fd, bytes + done, length - done, (off_t)done);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) return lk_error_set(error, LK_ERR_IO, "%s: read error: %s", name, strerror(errno));
        if (n == 0) break;
        done += (size_t)n;
    }
    struct stat after;
    if (done < length || fstat(fd, &after) != 0 || after.st_size != info->st_size ||
        after.st_mtim.tv_sec != info->st_mtim.tv_sec || after.st_mtim.tv_nsec != info->st_mtim.tv_nsec)
        return lk_error_set(error, LK_ERR_IO,
                            "%s: read error: the file changed while it was read (%llu bytes when opened)", name,
                            (unsigned long long)info->st_size);
    return LK_OK;
}

lk_status lk__read_opened(int fd, const struct stat *info, const char *name, size_t max_bytes, char **data,
                          size_t *size, lk_error *error)
{
    *data = NULL;
    *size = 0;
    if (max_bytes == 0 || max_bytes == SIZE_MAX) max_bytes = SIZE_MAX - 1;
    if ((unsigned long long)info->st_size > (unsigned long long)max_bytes)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: the file has %llu bytes, more than the memory budget of %zu bytes", name,
                            (unsigned long long)info->st_size, max_bytes);
    size_t length = (size_t)info->st_size;
    char *buffer = lk__alloc_random_access(length + 1, 1, false); /* huge pages for big files */
    if (!buffer) return lk_error_set(error, LK_ERR_NOMEM, "%s: cannot allocate %zu bytes", name, length + 1);
    lk_status status = lk__read_prefix(fd, info, name, length, buffer, error);
    if (status != LK_OK) {
        free(buffer);
        return status;
    }
    buffer[length] = '\0';
    *data = buffer;
    *size = length;
    return LK_OK;
}

lk_status lk__read_file(const char *path, size_t max_bytes, char **data, size_t *size, lk_error *error)
{
    *data = NULL;
    *size = 0;
    int fd;
    struct stat info;
    lk_status status = lk__open_input(NULL, path, &fd, &info, error);
    if (status != LK_OK) return status;
    status = lk__read_opened(fd, &info, path, max_bytes, data, size, error);
    close(fd);
    return status;
}

lk_status lk__input_too_large(const char *name, unsigned long long size, const lk__budget *budget, lk_error *error)
{
    if (budget->held)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: the file has %llu bytes, more than the memory budget of %zu bytes (%zu already held)",
                            name, size, budget->limit, budget->held);
    return lk_error_set(error, LK_ERR_LIMIT, "%s: the file has %llu bytes, more than the memory budget of %zu bytes",
                        name, size, budget->limit);
}

lk_status lk__read_file_charged(const char *path, lk__budget *budget, char **data, size_t *size, lk_error *error)
{
    *data = NULL;
    *size = 0;
    int fd;
    struct stat info;
    lk_status status = lk__open_input(NULL, path, &fd, &info, error);
    if (status != LK_OK) return status;
    /* Refused before a byte is read when it cannot fit what is left. */
    if ((unsigned long long)info.st_size > (unsigned long long)lk__budget_room(budget))
        status = lk__input_too_large(path, (unsigned long long)info.st_size, budget, error);
    else
        status = lk__read_opened(fd, &info, path, 0, data, size, error);
    close(fd);
    if (status == LK_OK && !lk__budget_charge(budget, *size, 1)) {
        status = lk__input_too_large(path, *size, budget, error);
        free(*data);
        *data = NULL;
        *size = 0;
    }
    return status;
}

/* The temporary file sits next to the output (rename must not cross file
 * systems) and is named ".NAME.tmp-XXXXXX": hidden, so that a directory
 * listing, a shell glob such as *.obj or `lodkit serve` (which refuses dot
 * files) never takes a half-written file for an output, and still
 * recognisable when a kill -9 leaves it behind (a killed process cannot
 * remove it). Created with O_EXCL and mode 0666 so the kernel applies the
 * umask: mkstemp's 0600 would need umask() to restore the usual mode, and
 * umask() changes process-wide state other threads may be relying on. */
enum { LK__TEMP_SUFFIX_LENGTH = 6 };

static void atomic_temp_name(char *temp, const char *path, size_t directory_length, const char *name,
                             size_t name_length, const char *tag, unsigned long long seed)
{
    static const char alphabet[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
    char suffix[LK__TEMP_SUFFIX_LENGTH + 1];
    for (int i = 0; i < LK__TEMP_SUFFIX_LENGTH; i++) {
        /* splitmix64 step: consecutive seeds give unrelated letters. */
        seed += 0x9E3779B97F4A7C15ull;
        unsigned long long z = seed;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        z ^= z >> 31;
        suffix[i] = alphabet[z % (sizeof alphabet - 1)];
    }
    suffix[LK__TEMP_SUFFIX_LENGTH] = '\0';
    memcpy(temp, path, directory_length);
    sprintf(temp + directory_length, ".%.*s.%s-%s", (int)name_length, name, tag, suffix);
}

/* A seed that differs between processes, calls and instants. */
static unsigned long long temp_seed(const void *salt)
{
    struct timespec now;
    clock_gettime(CLOCK_REALTIME, &now);
    unsigned long long seed = (unsigned long long)now.tv_sec * 1000000007ull + (unsigned long long)now.tv_nsec;
    return seed ^ (unsigned long long)getpid() << 32 ^ (unsigned long long)(uintptr_t)salt;
}

/* The temporary file's stdio stream writes through these, so that the errno
 * of the first failed write (ENOSPC, EFBIG, EIO) is kept: stdio only keeps a
 * sticky error flag, and by the time the output is committed errno is long
 * gone. */
struct lk__atomic_sink {
    int fd;
    int first_errno;
};

static ssize_t atomic_sink_write(void *cookie, const char *data, size_t size)
{
    lk__atomic_sink *sink = cookie;
    size_t done = 0;
    while (done < size) {
        ssize_t wrote = write(sink->fd, data + done, size - done);
        if (wrote < 0 && errno == EINTR) continue;
        if (wrote <= 0) {
            if (!sink->first_errno) sink->first_errno = wrote < 0 ? errno : EIO;
            return done ? (ssize_t)done : -1;
        }
        done += (size_t)wrote;
    }
    return (ssize_t)done;
}

static int atomic_sink_close(void *cookie)
{
    lk__atomic_sink *sink = cookie;
    int result = close(sink->fd);
    if (result != 0 && !sink->first_errno) sink->first_errno = errno;
    sink->fd = -1;
    return result;
}

lk_status lk__atomic_open(lk__atomic_file *out, const char *path, lk_error *error)
{
    memset(out, 0, sizeof *out);
    const char *slash = strrchr(path, '/');
    const char *name = slash ? slash + 1 : path;
    size_t length = strlen(path), directory_length = (size_t)(name - path), name_length = strlen(name);
    if (name_length == 0) return lk_error_set(error, LK_ERR_IO, "%s: not a file name (ends in '/')", path);
    /* Renaming over a device or a FIFO would replace it with a plain file
     * (as root, /dev/null itself), over a directory would fail late: refuse
     * anything but a regular file (a symbolic link is followed for this
     * check; the rename then replaces the link itself). */
    struct stat existing;
    if (stat(path, &existing) == 0 && !S_ISREG(existing.st_mode))
        return lk_error_set(error, LK_ERR_IO, "%s: exists and is not a regular file; not replacing it", path);
    /* ".", ".tmp-" and the suffix must fit in one directory entry: shorten
     * the copied name if the output's own name is near the limit. */
    size_t extra = 1 + 5 + LK__TEMP_SUFFIX_LENGTH;
    if (name_length > LK__NAME_MAX - extra) name_length = LK__NAME_MAX - extra;
    out->final_path = malloc(length + 1);
    out->temp_path = malloc(directory_length + name_length + extra + 1);
    if (!out->final_path || !out->temp_path) {
        free(out->final_path);
        free(out->temp_path);
        memset(out, 0, sizeof *out);
        return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", path);
    }
    memcpy(out->final_path, path, length + 1);
    unsigned long long seed = temp_seed(out);
    int fd = -1, saved_errno = 0;
    for (int attempt = 0; attempt < 100 && fd < 0; attempt++) {
        atomic_temp_name(out->temp_path, path, directory_length, name, name_length, "tmp",
                         seed + (unsigned long long)attempt * 977);
        fd = open(out->temp_path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0666);
        saved_errno = errno;
        if (fd < 0 && saved_errno != EEXIST) break;
    }
    if (fd < 0) {
        /* Name the directory: "No such file or directory" is about it. */
        int shown = directory_length > 1 ? (int)directory_length - 1 : (int)directory_length;
        lk_status status =
            lk_error_set(error, LK_ERR_IO, "%s: cannot create a file in the directory '%.*s': %s", path,
                         directory_length ? shown : 1, directory_length ? path : ".", strerror(saved_errno));
        free(out->final_path);
        free(out->temp_path);
        memset(out, 0, sizeof *out);
        return status;
    }
    out->sink = malloc(sizeof *out->sink);
    if (out->sink) {
        out->sink->fd = fd;
        out->sink->first_errno = 0;
        cookie_io_functions_t functions = {NULL, atomic_sink_write, NULL, atomic_sink_close};
        out->file = fopencookie(out->sink, "wb", functions);
    }
    if (!out->file) {
        saved_errno = out->sink ? errno : ENOMEM;
        close(fd);
        unlink(out->temp_path);
        free(out->sink);
        free(out->final_path);
        free(out->temp_path);
        memset(out, 0, sizeof *out);
        return lk_error_set(error, LK_ERR_IO, "%s: cannot open the temporary file: %s", path, strerror(saved_errno));
    }
    return LK_OK;
}

lk_status lk__atomic_commit(lk__atomic_file *out, lk_error *error)
{
    /* A write error (ENOSPC, EIO, EFBIG) may have been met by an earlier
     * buffered fwrite (sticky in ferror) or only now by the flush, the fsync
     * or the close; report the first errno seen. The fsync makes the rename
     * publish data that is on disk, not only a name. */
    lk_status status = LK_OK;
    int failure = 0;
    if (fflush(out->file) != 0 || ferror(out->file)) failure = out->sink->first_errno ? out->sink->first_errno : EIO;
    if (!failure && fsync(out->sink->fd) != 0) failure = errno;
    if (fclose(out->file) != 0 && !failure) failure = out->sink->first_errno ? out->sink->first_errno : EIO;
    out->file = NULL;
    free(out->sink);
    out->sink = NULL;
    if (failure) {
        status = lk_error_set(error, LK_ERR_IO, "%s: write error: %s", out->final_path, strerror(failure));
        unlink(out->temp_path);
    } else if (rename(out->temp_path, out->final_path) != 0) {
        status = lk_error_set(error, LK_ERR_IO, "%s: cannot rename the temporary file over it: %s", out->final_path,
                              strerror(errno));
        unlink(out->temp_path);
    }
    free(out->final_path);
    free(out->temp_path);
    memset(out, 0, sizeof *out);
    return status;
}

lk_status lk__atomic_fail(lk__atomic_file *out, lk_error *error)
{
    int reason = out->sink ? out->sink->first_errno : 0;
    lk_status status = error ? error->status : LK_ERR_IO;
    if (error && reason) {
        const char *text = strerror(reason);
        if (!strstr(error->message, text)) {
            size_t length = strlen(error->message);
            snprintf(error->message + length, sizeof error->message - length, ": %s", text);
        }
    }
    lk__atomic_abort(out);
    return status;
}

void lk__atomic_abort(lk__atomic_file *out)
{
    if (out->file) fclose(out->file);
    free(out->sink);
    if (out->temp_path) unlink(out->temp_path);
    free(out->final_path);
    free(out->temp_path);
    memset(out, 0, sizeof *out);
}

lk_status lk__temp_dir_create(const char *path, const char *tag, char **temp_path, lk_error *error)
{
    *temp_path = NULL;
    const char *slash = strrchr(path, '/');
    const char *name = slash ? slash + 1 : path;
    size_t directory_length = (size_t)(name - path), name_length = strlen(name);
    if (name_length == 0) return lk_error_set(error, LK_ERR_IO, "%s: not a folder name (ends in '/')", path);
    size_t extra = 1 + 1 + strlen(tag) + 1 + LK__TEMP_SUFFIX_LENGTH;
    if (extra >= LK__NAME_MAX) return lk_error_set(error, LK_ERR_INVALID, "lk__temp_dir_create: tag too long");
    if (name_length > LK__NAME_MAX - extra) name_length = LK__NAME_MAX - extra;
    char *temp = malloc(directory_length + name_length + extra + 1);
    if (!temp) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", path);
    unsigned long long seed = temp_seed(temp_path);
    int created = -1, saved_errno = 0;
    for (int attempt = 0; attempt < 100 && created != 0; attempt++) {
        atomic_temp_name(temp, path, directory_length, name, name_length, tag,
                         seed + (unsigned long long)attempt * 977);
        created = mkdir(temp, 0777);
        saved_errno = errno;
        if (created != 0 && saved_errno != EEXIST) break;
    }
    if (created != 0) {
        int shown = directory_length > 1 ? (int)directory_length - 1 : (int)directory_length;
        lk_status status =
            lk_error_set(error, LK_ERR_IO, "%s: cannot create a folder in the directory '%.*s': %s", path,
                         directory_length ? shown : 1, directory_length ? path : ".", strerror(saved_errno));
        free(temp);
        return status;
    }
    *temp_path = temp;
    return LK_OK;
}

/* ---- number parsing ---------------------------------------------------- */

const char *lk__skip_line(const char *p, const char *end)
{
    const char *newline = memchr(p, '\n', (size_t)(end - p));
    return newline ? newline + 1 : end;
}

lk_status lk__error_at_line_v(lk_error *error, lk_status status, const char *name, size_t line, const char *format,
                              va_list args)
{
    char message[400];
    vsnprintf(message, sizeof message, format, args);
    return lk_error_set(error, status, "%s:%zu: %s", name, line, message);
}

lk_status lk__error_at_line(lk_error *error, lk_status status, const char *name, size_t line, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_line_v(error, status, name, line, format, args);
    va_end(args);
    return status;
}

lk_status lk__error_at_byte_v(lk_error *error, lk_status status, const char *name, size_t offset, const char *format,
                              va_list args)
{
    char message[400];
    vsnprintf(message, sizeof message, format, args);
    return lk_error_set(error, status, "%s: byte %zu: %s", name, offset, message);
}

lk_status lk__error_at_byte(lk_error *error, lk_status status, const char *name, size_t offset, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_byte_v(error, status, name, offset, format, args);
    va_end(args);
    return status;
}

void lk__quote_token(const char *p, const char *end, char *out, size_t out_size)
{
    p = lk__skip_spaces(p, end);
    size_t length = 0;
    while (p + length < end && !lk__is_space(p[length]) && length < 24 && length + 1 < out_size) length++;
    memcpy(out, p, length);
    out[length] = '\0';
}

bool lk__word_equals(const char *p, size_t len, const char *word)
{
    size_t i = 0;
    for (; i < len && word[i]; i++) {
        char a = p[i], b = word[i];
        if (a >= 'A' && a <= 'Z') a = (char)(a - 'A' + 'a');
        if (b >= 'A' && b <= 'Z') b = (char)(b - 'A' + 'a');
        if (a != b) return false;
    }
    return i == len && word[i] == '\0';
}

static const double lk__pow10_exact[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                           1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static bool lk__parse_special(const char **p, const char *end, bool negative, double *out)
{
    const char *s = *p;
    size_t left = (size_t)(end - s);
    if (left >= 3 && lk__word_equals(s, 3, "nan")) {
        s += 3;
        /* nan(...) payloads */
        if (s < end && *s == '(') {
            while (s < end && *s != ')' && *s != '\n') s++;
            if (s < end && *s == ')') s++;
        }
        *out = negative ? -NAN : NAN;
    } else if (left >= 8 && lk__word_equals(s, 8, "infinity")) {
        s += 8;
        *out = negative ? -INFINITY : INFINITY;
    } else if (left >= 3 && lk__word_equals(s, 3, "inf")) {
        s += 3;
        *out = negative ? -INFINITY : INFINITY;
    } else {
        return false;
    }
    *p = s;
    return true;
}

bool lk__parse_double(const char **p, const char *end, double *out)
{
    const char *s = lk__skip_spaces(*p, end);
    const char *start = s;
    bool negative = false;
    if (s < end && (*s == '-' || *s == '+')) {
        negative = *s == '-';
        s++;
    }
    if (s < end && (*s == 'n' || *s == 'N' || *s == 'i' || *s == 'I')) {
        if (!lk__parse_special(&s, end, negative, out)) return false;
        *p = s;
        return true;
    }
    /* Fast path for what model files hold ("-0.296502", "12", "5.", ".5"):
     * at most 19 digits and no exponent. It computes what the general path
     * below computes for such numbers, in one loop without its bookkeeping;
     * anything else goes on to the general path. */
    {
        const char *q = s;
        uint64_t digits_value = 0;
        int digit_count = 0, fraction_digits = 0;
        while (q < end && (unsigned)(*q - '0') <= 9 && digit_count < 20) {
            digits_value = digits_value * 10 + (uint64_t)(*q++ - '0');
            digit_count++;
        }
        if (q < end && *q == '.') {
            q++;
            while (q < end && (unsigned)(*q - '0') <= 9 && digit_count < 20) {
                digits_value = digits_value * 10 + (uint64_t)(*q++ - '0');
                digit_count++;
                fraction_digits++;
            }
        }
        bool exponent_follows = q < end && (*q == 'e' || *q == 'E');
        if (digit_count > 0 && digit_count <= 19 && !exponent_follows && digits_value <= (1ull << 53) &&
            fraction_digits <= 22) {
            double value = (double)digits_value / lk__pow10_exact[fraction_digits];
            *out = negative ? -value : value;
            *p = q;
            return true;
        }
    }
    uint64_t mantissa = 0;
    int digits = 0;  /* significant digits kept in mantissa */
    int dropped = 0; /* integer digits beyond 19 (scale up) */
    int exponent = 0;
    bool any_digit = false;
    bool exact = true;
    while (s < end && *s >= '0' && *s <= '9') {
        any_digit = true;
        if (digits < 19) {
            if (mantissa || *s != '0') {
                mantissa = mantissa * 10 + (uint64_t)(*s - '0');
                digits++;
            }
        } else {
            dropped++;
            if (*s != '0') exact = false;
        }
        s++;
    }
    exponent += dropped;
    if (s < end && *s == '.') {
        s++;
        while (s < end && *s >= '0' && *s <= '9') {
            any_digit = true;
            if (digits < 19) {
                if (mantissa || *s != '0') {
                    mantissa = mantissa * 10 + (uint64_t)(*s - '0');
                    digits++;
                }
                exponent--;
            } else if (*s != '0') {
                exact = false;
            }
            s++;
        }
    }
    if (!any_digit) return false;
    if (s < end && (*s == 'e' || *s == 'E')) {
        const char *e = s + 1;
        bool exponent_negative = false;
        if (e < end && (*e == '-' || *e == '+')) {
            exponent_negative = *e == '-';
            e++;
        }
        if (e < end && *e >= '0' && *e <= '9') {
            int value = 0;
            while (e < end && *e >= '0' && *e <= '9') {
                if (value < 100000) value = value * 10 + (*e - '0');
                e++;
            }
            exponent += exponent_negative ? -value : value;
            s = e;
        }
    }
    double value;
    if (exact && mantissa <= (1ull << 53) && exponent >= -22 && exponent <= 22) {
        value = (double)mantissa;
        if (exponent < 0)
            value /= lk__pow10_exact[-exponent];
        else
            value *= lk__pow10_exact[exponent];
    } else if (mantissa == 0) {
        value = 0.0;
    } else {
        /* Rare: long mantissas or big exponents. strtod needs a terminated copy. */
        char copy[128];
        size_t length = (size_t)(s - start);
        if (length >= sizeof copy) {
            /* Absurdly long literal: fall back to the truncated mantissa. */
            value = (double)mantissa * pow(10.0, exponent);
            if (negative) value = -value;
            *out = value;
            *p = s;
            return true;
        }
        memcpy(copy, start, length);
        copy[length] = '\0';
        value = strtod(copy, NULL);
        *out = value;
        *p = s;
        return true;
    }
    *out = negative ? -value : value;
    *p = s;
    return true;
}

bool lk__parse_int64(const char **p, const char *end, long long *out)
{
    const char *s = lk__skip_spaces(*p, end);
    bool negative = false;
    if (s < end && (*s == '-' || *s == '+')) {
        negative = *s == '-';
        s++;
    }
    if (s >= end || *s < '0' || *s > '9') return false;
    unsigned long long value = 0;
    /* 18 digits cannot overflow: only the digits after them are checked. */
    const char *unchecked_end = end - s > 18 ? s + 18 : end;
    while (s < unchecked_end && (unsigned)(*s - '0') <= 9) value = value * 10 + (unsigned)(*s++ - '0');
    while (s < end && *s >= '0' && *s <= '9') {
        unsigned digit = (unsigned)(*s - '0');
        if (value > (9223372036854775807ull - digit) / 10) return false;
        value = value * 10 + digit;
        s++;
    }
    *out = negative ? -(long long)value : (long long)value;
    *p = s;
    return true;
}

lk_status lk__check_claim(unsigned long long count, size_t min_bytes_each, size_t available, size_t bytes_per_element,
                          const lk__budget *budget, const char *what, const char *where, lk_error *error)
{
    if (count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %llu %s is more than lodkit supports (%zu)", where, count, what,
                            (size_t)LK_MAX_ELEMENTS);
    if (min_bytes_each && count > available / min_bytes_each)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: header claims %llu %s but only %zu bytes follow (truncated or corrupt file)", where,
                            count, what, available);
    if (bytes_per_element && count > lk__budget_room(budget) / bytes_per_element)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %llu %s would need more than the memory budget of %zu bytes",
                            where, count, what, budget->limit);
    return LK_OK;
}

/* lk__format_float's answer from a single printf: the value's first 17
 * significant digits ("%.16e", exact rounding), rounded here to 6, 7, 8 and
 * 9 digits and laid out as "%.*g" lays them out; each is checked to read back
 * as the value through an exact decimal-to-double conversion (Clinger's:
 * at most 9 digits times an exact power of ten) and the rounding of that
 * double to float. Returns the length, or -1 whenever that could differ
 * from printf and strtof (a tie in the 17 digits, a double halfway between
 * two floats, exponents out of the exact range, zero, denormals, huge or
 * non-finite values): the caller then takes the slow road. */
static int format_float_fast(char out[32], float value)
{
    double magnitude = fabs((double)value);
    if (!(magnitude >= 1e-30 && magnitude <= 1e30)) return -1;
    char scientific[40];
    snprintf(scientific, sizeof scientific, "%.16e", magnitude);
    char digits[17];
    digits[0] = scientific[0];
    memcpy(digits + 1, scientific + 2, 16); /* "d.dddddddddddddddde+XX" */
    int exponent10 = atoi(scientific + 19);
    for (int precision = 6; precision <= 9; precision++) {
        /* Round the 17 digits to `precision`; "5000..." may have been a tie
         * or rounded from either side of one. */
        int rest = precision;
        bool tie = digits[rest] == '5';
        for (int i = rest + 1; tie && i < 17; i++) tie = digits[i] == '0';
        if (tie) return -1;
        char rounded[10];
        memcpy(rounded, digits, (size_t)precision);
        int exponent = exponent10;
        if (digits[rest] >= '5') {
            int i = precision - 1;
            while (i >= 0 && rounded[i] == '9') rounded[i--] = '0';
            if (i >= 0) {
                rounded[i]++;
            } else {
                rounded[0] = '1'; /* 9.99..9 -> 10.0..0 */
                exponent++;
            }
        }
        /* Does it read back as the value? */
        uint64_t mantissa = 0;
        for (int i = 0; i < precision; i++) mantissa = mantissa * 10 + (uint64_t)(rounded[i] - '0');
        int scale = exponent - (precision - 1);
        if (scale < -22 || scale > 22) return -1;
        double back =
            scale < 0 ? (double)mantissa / lk__pow10_exact[-scale] : (double)mantissa * lk__pow10_exact[scale];
        uint64_t bits;
        memcpy(&bits, &back, sizeof bits);
        const uint64_t below_float = ((uint64_t)1 << 29) - 1;     /* double mantissa bits a float lacks */
        if ((bits & below_float) == (uint64_t)1 << 28) return -1; /* halfway: double rounding could differ */
        if ((float)back != (float)magnitude) continue;
        /* "%.*g": trailing zeros go, and the point when nothing follows it. */
        int kept = precision;
        size_t at = 0;
        if (value < 0) out[at++] = '-';
        if (exponent < -4 || exponent >= precision) {
            while (kept > 1 && rounded[kept - 1] == '0') kept--;
            out[at++] = rounded[0];
            if (kept > 1) {
                out[at++] = '.';
                memcpy(out + at, rounded + 1, (size_t)(kept - 1));
                at += (size_t)(kept - 1);
            }
            at += (size_t)sprintf(out + at, "e%c%02d", exponent < 0 ? '-' : '+', abs(exponent));
        } else {
            int integer_digits = exponent >= 0 ? exponent + 1 : 0;
            while (kept > integer_digits && rounded[kept - 1] == '0') kept--;
            if (exponent >= 0) {
                memcpy(out + at, rounded, (size_t)integer_digits);
                at += (size_t)integer_digits;
            } else {
                out[at++] = '0';
            }
            if (kept > integer_digits) {
                out[at++] = '.';
                for (int zeros = -exponent - 1; zeros > 0; zeros--) out[at++] = '0';
                memcpy(out + at, rounded + integer_digits, (size_t)(kept - integer_digits));
                at += (size_t)(kept - integer_digits);
            }
        }
        out[at] = '\0';
        return (int)at;
    }
    return -1;
}

int lk__format_float(char *buffer, size_t size, float value)
{
    char fast[32];
    int fast_length = format_float_fast(fast, value);
    if (fast_length >= 0 && (size_t)fast_length < size) {
        memcpy(buffer, fast, (size_t)fast_length + 1);
        return fast_length;
    }
    /* %.9g always round-trips a float; try shorter first for readability. */
    for (int precision = 6; precision <= 9; precision++) {
        int length = snprintf(buffer, size, "%.*g", precision, (double)value);
        if (strtof(buffer, NULL) == value) return length;
    }
    return snprintf(buffer, size, "%.9g", (double)value);
}

double lk__now(void)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)now.tv_sec + (double)now.tv_nsec * 1e-9;
}

void lk__memory_trace(const char *stage)
{
    static int enabled = -1;
    if (enabled < 0) enabled = getenv("LODKIT_MEMORY_TRACE") != NULL;
    if (!enabled) return;
    long resident = -1, peak = -1; /* KiB */
    FILE *status = fopen("/proc/self/status", "r");
    if (status) {
        char line[256];
        while (fgets(line, sizeof line, status)) {
            if (!strncmp(line, "VmRSS:", 6)) resident = strtol(line + 6, NULL, 10);
            if (!strncmp(line, "VmHWM:", 6)) peak = strtol(line + 6, NULL, 10);
        }
        fclose(status);
    }
    fprintf(stderr, "memory: %-32s resident %8.1f MiB, peak %8.1f MiB\n", stage, resident / 1024.0, peak / 1024.0);
}

void lk__mat4_identity(double m[16])
{
    for (int i = 0; i < 16; i++) m[i] = (i % 5 == 0) ? 1.0 : 0.0;
}

void lk__mat4_multiply(const double a[16], const double b[16], double out[16])
{
    double result[16];
    for (int column = 0; column < 4; column++)
        for (int row = 0; row < 4; row++) {
            double sum = 0.0;
            for (int k = 0; k < 4; k++) sum += a[k * 4 + row] * b[column * 4 + k];
            result[column * 4 + row] = sum;
        }
    memcpy(out, result, sizeof result);
}

bool lk__notes_vadd(lk__buffer *notes, const char *format, va_list args)
{
    char line[320];
    int length = vsnprintf(line, sizeof line, format, args);
    if (length < 0) return false;
    if ((size_t)length >= sizeof line) length = (int)sizeof line - 1;
    /* The same note twice says nothing new. */
    const char *text = (const char *)notes->data;
    for (size_t start = 0; start < notes->size;) {
        const char *end = memchr(text + start, '\n', notes->size - start);
        size_t line_length = end ? (size_t)(end - (text + start)) : notes->size - start;
        if (line_length == (size_t)length && memcmp(text + start, line, line_length) == 0) return false;
        start += line_length + 1;
    }
    if (!lk__buffer_append(notes, line, (size_t)length)) return false;
    lk__buffer_append(notes, "\n", 1);
    return true;
}

/* Places the value of rank `nth` at values[nth], smaller or equal ones
 * before it and greater or equal ones after it: a three-way
 * quickselect (hashed median-of-three pivots, deterministic) on floats. */
void lk__select_float(float *values, size_t count, size_t nth)
{
    size_t lo = 0, hi = count;
    while (hi - lo > 1) {
        size_t length = hi - lo;
        uint64_t h = lk__mix64(((uint64_t)lo << 32) ^ hi);
        float a = values[lo + (size_t)(h % length)], b = values[lo + (size_t)((h >> 21) % length)],
              c = values[lo + (size_t)((h >> 42) % length)];
        float pivot = a < b ? (b < c ? b : (a < c ? c : a)) : (a < c ? a : (b < c ? c : b));
        size_t less = lo, i = lo, greater = hi;
        while (i < greater) {
            float value = values[i];
            if (value < pivot) {
                values[i++] = values[less];
                values[less++] = value;
            } else if (value > pivot) {
                values[i] = values[--greater];
                values[greater] = value;
            } else {
                i++;
            }
        }
        if (nth < less)
            hi = less;
        else if (nth >= greater)
            lo = greater;
        else
            return;
    }
}
