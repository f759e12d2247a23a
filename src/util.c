/* Shared helpers: errors, checked allocation, files, number parsing. */
#include "internal.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

const char *lk_version(void) { return LK_VERSION_STRING; }

void lk_error_clear(lk_error *error)
{
    if (!error) return;
    error->status = LK_OK;
    error->message[0] = '\0';
}

lk_status lk_error_set(lk_error *error, lk_status status, const char *format, ...)
{
    if (error) {
        va_list args;
        va_start(args, format);
        vsnprintf(error->message, sizeof error->message, format, args);
        va_end(args);
        error->status = status;
    }
    return status;
}

const char *lk_status_string(lk_status status)
{
    switch (status) {
    case LK_OK: return "ok";
    case LK_ERR_IO: return "i/o error";
    case LK_ERR_PARSE: return "parse error";
    case LK_ERR_RANGE: return "value out of range";
    case LK_ERR_LIMIT: return "size limit exceeded";
    case LK_ERR_NOMEM: return "out of memory";
    case LK_ERR_INVALID: return "invalid argument";
    case LK_ERR_UNSUPPORTED: return "unsupported";
    case LK_ERR_TRUNCATED: return "truncated input";
    }
    return "unknown error";
}

/* ---- allocation -------------------------------------------------------- */

void *lk__malloc_array(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    size_t bytes = count * size;
    return malloc(bytes ? bytes : 1);
}

void *lk__calloc_array(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    if (count == 0 || size == 0) return calloc(1, 1);
    return calloc(count, size);
}

void *lk__realloc_array(void *ptr, size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    size_t bytes = count * size;
    return realloc(ptr, bytes ? bytes : 1);
}

bool lk__buffer_reserve(lk__buffer *buffer, size_t extra)
{
    if (extra > SIZE_MAX - buffer->size) return false;
    size_t need = buffer->size + extra;
    if (need <= buffer->capacity) return true;
    size_t capacity = buffer->capacity ? buffer->capacity : 256;
    while (capacity < need) {
        if (capacity > SIZE_MAX / 2) { capacity = need; break; }
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

lk_status lk__read_file(const char *path, char **data, size_t *size, lk_error *error)
{
    *data = NULL;
    *size = 0;
    FILE *file = fopen(path, "rb");
    if (!file) return lk_error_set(error, LK_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat info;
    if (fstat(fileno(file), &info) != 0 || !S_ISREG(info.st_mode)) {
        fclose(file);
        return lk_error_set(error, LK_ERR_IO, "%s: not a regular file", path);
    }
    if ((unsigned long long)info.st_size >= (unsigned long long)SIZE_MAX) {
        fclose(file);
        return lk_error_set(error, LK_ERR_LIMIT, "%s: file too large", path);
    }
    size_t length = (size_t)info.st_size;
    char *buffer = malloc(length + 1);
    if (!buffer) {
        fclose(file);
        return lk_error_set(error, LK_ERR_NOMEM, "%s: cannot allocate %zu bytes", path, length + 1);
    }
    size_t got = length ? fread(buffer, 1, length, file) : 0;
    int failed = ferror(file);
    fclose(file);
    if (failed || got != length) {
        free(buffer);
        return lk_error_set(error, LK_ERR_IO, "%s: read error", path);
    }
    buffer[length] = '\0';
    *data = buffer;
    *size = length;
    return LK_OK;
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
    struct stat info;
    if (stat(path, &info) == 0 && S_ISREG(info.st_mode) &&
        (unsigned long long)info.st_size > (unsigned long long)lk__budget_room(budget))
        return lk__input_too_large(path, (unsigned long long)info.st_size, budget, error);
    lk_status status = lk__read_file(path, data, size, error);
    if (status != LK_OK) return status;
    /* It may have grown since stat. */
    if (!lk__budget_charge(budget, *size, 1)) {
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
enum { LK__TEMP_SUFFIX_LENGTH = 6, LK__NAME_MAX = 255 };

static void atomic_temp_name(char *temp, const char *path, size_t directory_length, const char *name,
                             size_t name_length, unsigned long long seed)
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
    sprintf(temp + directory_length, ".%.*s.tmp-%s", (int)name_length, name, suffix);
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
    struct timespec now;
    clock_gettime(CLOCK_REALTIME, &now);
    unsigned long long seed = (unsigned long long)now.tv_sec * 1000000007ull + (unsigned long long)now.tv_nsec;
    seed ^= (unsigned long long)getpid() << 32 ^ (unsigned long long)(uintptr_t)out;
    int fd = -1, saved_errno = 0;
    for (int attempt = 0; attempt < 100 && fd < 0; attempt++) {
        atomic_temp_name(out->temp_path, path, directory_length, name, name_length, seed + (unsigned long long)attempt * 977);
        fd = open(out->temp_path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0666);
        saved_errno = errno;
        if (fd < 0 && saved_errno != EEXIST) break;
    }
    if (fd < 0) {
        /* Name the directory: "No such file or directory" is about it. */
        int shown = directory_length > 1 ? (int)directory_length - 1 : (int)directory_length;
        lk_status status = lk_error_set(error, LK_ERR_IO, "%s: cannot create a file in the directory '%.*s': %s", path,
                                        directory_length ? shown : 1, directory_length ? path : ".",
                                        strerror(saved_errno));
        free(out->final_path);
        free(out->temp_path);
        memset(out, 0, sizeof *out);
        return status;
    }
    out->file = fdopen(fd, "wb");
    if (!out->file) {
        saved_errno = errno;
        close(fd);
        unlink(out->temp_path);
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
    errno = 0;
    if (fflush(out->file) != 0) failure = errno ? errno : EIO;
    bool earlier = !failure && ferror(out->file);
    if (!failure && !earlier && fsync(fileno(out->file)) != 0) failure = errno ? errno : EIO;
    if (fclose(out->file) != 0 && !failure) failure = errno ? errno : EIO;
    out->file = NULL;
    if (failure || earlier) {
        /* After a failed buffered write the errno is long gone. */
        status = failure ? lk_error_set(error, LK_ERR_IO, "%s: write error: %s", out->final_path, strerror(failure))
                         : lk_error_set(error, LK_ERR_IO, "%s: write error (disk full or I/O error)", out->final_path);
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

void lk__atomic_abort(lk__atomic_file *out)
{
    if (out->file) fclose(out->file);
    if (out->temp_path) unlink(out->temp_path);
    free(out->final_path);
    free(out->temp_path);
    memset(out, 0, sizeof *out);
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

lk_status lk__error_at_line(lk_error *error, lk_status status, const char *name, size_t line, const char *format,
                            ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_line_v(error, status, name, line, format, args);
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

static const double lk__pow10_exact[23] = {
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22
};

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
    uint64_t mantissa = 0;
    int digits = 0;          /* significant digits kept in mantissa */
    int dropped = 0;         /* integer digits beyond 19 (scale up) */
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
        if (exponent < 0) value /= lk__pow10_exact[-exponent];
        else value *= lk__pow10_exact[exponent];
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

lk_status lk__check_claim(unsigned long long count, size_t min_bytes_each, size_t available,
                          size_t bytes_per_element, const lk__budget *budget, const char *what,
                          const char *where, lk_error *error)
{
    if (count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %llu %s is more than lodkit supports (%zu)", where, count,
                            what, (size_t)LK_MAX_ELEMENTS);
    if (min_bytes_each && count > available / min_bytes_each)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: header claims %llu %s but only %zu bytes follow (truncated or corrupt file)",
                            where, count, what, available);
    if (bytes_per_element && count > lk__budget_room(budget) / bytes_per_element)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %llu %s would need more than the memory budget of %zu bytes",
                            where, count, what, budget->limit);
    return LK_OK;
}

int lk__format_float(char *buffer, size_t size, float value)
{
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
