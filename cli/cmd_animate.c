/* SPDX-License-Identifier: MIT */
/* lodkit animate: deformation-sensitive simplification of an animation into
 * a level set, measured frame by frame like the paper's Fig. 8. */
#define _GNU_SOURCE /* renameat2 (RENAME_EXCHANGE, glibc 2.28+), flock */
#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"

const cli_help animate_help = {
    "IN OUTDIR",
    "Simplify an animation (MD2, KMF, glTF morph targets or skins, Acclaim) with one\n"
    "connectivity for all frames: per-frame quadrics, the merged vertex placed per\n"
    "frame, pairs ranked by the worst frame (max, the paper's), the mean over\n"
    "frames (avg) or one frame (frame). Replaces OUTDIR whole (created if missing;\n"
    "it must be new, empty or an earlier run's set) with a set built in a hidden\n"
    "folder beside it (.OUTDIR.tmp-XXXXXX) and swapped in at once, listed in\n"
    "OUTDIR/.lodkit-animate:\n"
    "  STEM-SCHEME-LKK.EXT  level KK of the level set (KK/N of the triangles), in\n"
    "                       the input's format (.md2, .kmf; glTF, Acclaim: .gltf)\n"
    "  STEM-SCHEME.csv      per level and frame, Metro distances between the\n"
    "                       simplified and the original frame (model units),\n"
    "                       columns: level,ratio,frame,triangles,mean,rms,max,\n"
    "                       rms_forward,rms_backward,rms_percent (mean/rms: the\n"
    "                       larger of the two directions; max: the Hausdorff\n"
    "                       distance; rms_percent: rms in % of the diagonal of\n"
    "                       all original frames)\n"
    "  STEM-SCHEME-rms.png  heat map level x frame -> rms_percent (one colour\n"
    "                       scale for all schemes of the run)\n"
    "SCHEME is max, avg or frameK.\n"
    "Reads {animation-read} ('lodkit formats' says what each is).\n",
    NULL,
};

typedef struct level_summary {
    size_t triangles;
    size_t folds_from;
    double worst_rms; /* % of the diagonal */
    size_t worst_frame;
    double mean_rms; /* % of the diagonal, mean over measured frames */
} level_summary;

/* "faerie" from "dir/faerie.md2". */
static void path_stem(const char *path, char *stem, size_t size)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    snprintf(stem, size, "%s", base);
    char *dot = strrchr(stem, '.');
    if (dot && dot != stem) *dot = '\0';
}

/* The extension lk_animation_write should use for an input path. */
static const char *output_extension(const char *path)
{
    const char *dot = strrchr(path, '.');
    if (dot && !strcasecmp(dot, ".md2")) return "md2";
    if (dot && !strcasecmp(dot, ".kmf")) return "kmf";
    return "gltf";
}

/* ---- the output set ------------------------------------------------------
 * OUTDIR belongs to animate and is replaced whole. The new set is written
 * into a private hidden folder beside it, PARENT/.NAME.tmp-XXXXXX (same file
 * system; hidden like the library's temporary files), with a manifest
 * listing its files; then one renameat2(RENAME_EXCHANGE) swaps that folder
 * with OUTDIR, and the previous set, now at the hidden name, is deleted file
 * by file as its own manifest lists them. Readers of OUTDIR see the previous
 * complete set or the new one, never a mix; a failure or a kill -9 before the
 * swap leaves OUTDIR as it was (a killed run leaves its hidden folder behind,
 * safe to delete). Where the file system cannot exchange two names (NFS,
 * CIFS: EINVAL), OUTDIR is renamed away to .NAME.old-XXXXXX and the new set
 * renamed in: for that instant OUTDIR is missing, never mixed.
 * Two runs into one folder each build their own set; an flock on OUTDIR
 * orders their swaps (after the lock, the path must still name the locked
 * folder: the other run may have swapped it), so the folder always holds one
 * run's complete set: the last to finish. The lock is not what keeps the sets
 * whole (each step is one rename, and an old set is deleted by its own
 * manifest), so a file system without flock only loses the ordering. */
#define SET_MANIFEST ".lodkit-animate"
#define SET_MANIFEST_HEADER "# lodkit animate: the files of this set; the next run into this folder replaces them all\n"

typedef struct output_set {
    const char *shown; /* OUTDIR as given: what messages name */
    char *path;        /* OUTDIR with its parent resolved (realpath) */
    char *build;       /* the hidden folder the new set is written into, until it is swapped in */
    char **names;      /* the files of the new set */
    size_t count, capacity;
} output_set;

/* The manifest of the folder open as directory_fd (NUL-terminated, its header
 * checked), or NULL when it has none written by animate. */
static char *manifest_read(int directory_fd)
{
    int fd = openat(directory_fd, SET_MANIFEST, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) return NULL;
    struct stat info;
    char *text = NULL;
    size_t header = sizeof SET_MANIFEST_HEADER - 1;
    /* 1000 levels x 3 schemes of 500-byte names fit in 2 MB */
    if (fstat(fd, &info) == 0 && S_ISREG(info.st_mode) && info.st_size >= (off_t)header && info.st_size < 2 << 20)
        text = malloc((size_t)info.st_size + 1);
    size_t got = 0;
    while (text && got < (size_t)info.st_size) {
        ssize_t n = read(fd, text + got, (size_t)info.st_size - got);
        if (n <= 0) break;
        got += (size_t)n;
    }
    close(fd);
    if (text && (got != (size_t)info.st_size || memcmp(text, SET_MANIFEST_HEADER, header) != 0)) {
        free(text);
        return NULL;
    }
    if (text) text[got] = '\0';
    return text;
}

/* Whether the manifest lists NAME as a file of the set. */
static int manifest_lists(const char *manifest, const char *name)
{
    size_t length = strlen(name);
    for (const char *line = strchr(manifest, '\n'); line; line = strchr(line, '\n')) {
        line++;
        if (!strncmp(line, name, length) && (line[length] == '\n' || line[length] == '\0')) return 1;
    }
    return 0;
}

/* A name a manifest may list: one entry of the folder itself. */
static int set_name_valid(const char *name, size_t length)
{
    return length > 0 && !memchr(name, '/', length) && !memchr(name, '\n', length) &&
           !(length == 1 && name[0] == '.') && !(length == 2 && name[0] == '.' && name[1] == '.');
}

/* LK_OK when the folder at `path` is missing, empty, or holds an animate set
 * and nothing else: the manifest, and regular files it lists. Otherwise an
 * error naming (some of) the other entries: animate never deletes those. */
static lk_status set_check_owned(const char *path, const char *shown, lk_error *error)
{
    struct stat info;
    if (lstat(path, &info) != 0)
        return errno == ENOENT ? LK_OK : lk_error_set(error, LK_ERR_IO, "%s: %s", shown, strerror(errno));
    if (!S_ISDIR(info.st_mode)) return lk_error_set(error, LK_ERR_IO, "%s: exists and is not a folder", shown);
    int directory_fd = open(path, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    int list_fd = directory_fd < 0 ? -1 : dup(directory_fd);
    DIR *directory = list_fd < 0 ? NULL : fdopendir(list_fd);
    if (!directory) {
        lk_status status = lk_error_set(error, LK_ERR_IO, "%s: cannot read the folder: %s", shown, strerror(errno));
        if (list_fd >= 0) close(list_fd);
        if (directory_fd >= 0) close(directory_fd);
        return status;
    }
    char *manifest = manifest_read(directory_fd);
    char foreign[200] = "";
    size_t foreign_count = 0, used = 0;
    for (struct dirent *entry; (entry = readdir(directory));) {
        const char *name = entry->d_name;
        if (!strcmp(name, ".") || !strcmp(name, "..")) continue;
        if (manifest && !strcmp(name, SET_MANIFEST)) continue;
        struct stat entry_info = {0};
        int is_file = fstatat(directory_fd, name, &entry_info, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(entry_info.st_mode);
        if (manifest && is_file && manifest_lists(manifest, name)) continue;
        if (foreign_count++ < 3) {
            int is_folder = !is_file && S_ISDIR(entry_info.st_mode);
            int n = snprintf(foreign + used, sizeof foreign - used, "%s%.60s%s", used ? ", " : "", name,
                             is_folder ? "/" : "");
            used += n > 0 && (size_t)n < sizeof foreign - used ? (size_t)n : 0;
        }
    }
    closedir(directory);
    close(directory_fd);
    free(manifest);
    if (foreign_count == 0) return LK_OK;
    return lk_error_set(error, LK_ERR_IO,
                        "%s holds files lodkit animate did not write (%s%s); animate replaces the whole folder: "
                        "use a new or empty folder",
                        shown, foreign, foreign_count > 3 ? ", ..." : "");
}

/* Deletes the previous set once it is out of place: the files its manifest
 * lists, the manifest, the folder. Anything else in it stays, and is said. */
static void set_delete_folder(const char *folder, const char *shown)
{
    int directory_fd = open(folder, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    char *manifest = directory_fd < 0 ? NULL : manifest_read(directory_fd);
    for (const char *line = manifest ? strchr(manifest, '\n') : NULL; line && line[1]; line = strchr(line, '\n')) {
        line++;
        const char *end = strchr(line, '\n');
        size_t length = end ? (size_t)(end - line) : strlen(line);
        char name[512];
        struct stat info;
        if (set_name_valid(line, length) && length < sizeof name) {
            memcpy(name, line, length);
            name[length] = '\0';
            if (fstatat(directory_fd, name, &info, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(info.st_mode))
                unlinkat(directory_fd, name, 0);
        }
        if (!end) break;
    }
    if (manifest) unlinkat(directory_fd, SET_MANIFEST, 0);
    free(manifest);
    if (directory_fd >= 0) close(directory_fd);
    if (rmdir(folder) == 0) return;
    if (errno == ENOTEMPTY || errno == EEXIST)
        fprintf(stderr,
                "lodkit animate: %s: the previous set's folder also held files lodkit animate did not write: "
                "left them in %s\n",
                shown, folder);
    else
        fprintf(stderr, "lodkit animate: %s: cannot delete the previous set's folder %s: %s\n", shown, folder,
                strerror(errno));
}

/* Replaces every `from` in the error message with `to`. */
static void error_replace(lk_error *error, const char *from, const char *to)
{
    size_t length = strlen(from);
    char message[sizeof error->message];
    size_t used = 0;
    for (const char *p = error->message; *p && used + 1 < sizeof message;) {
        if (length && !strncmp(p, from, length)) {
            used += (size_t)snprintf(message + used, sizeof message - used, "%s", to);
            p += length;
        } else {
            message[used++] = *p++;
        }
        if (used >= sizeof message) used = sizeof message - 1;
    }
    message[used] = '\0';
    memcpy(error->message, message, used + 1);
}

/* lk_output_folder_create with the path malloc'ed into *created (free it). */
static lk_status folder_create(const char *path, const char *tag, char **created, lk_error *error)
{
    char buffer[8192];
    *created = NULL;
    lk_status status = lk_output_folder_create(path, tag, buffer, sizeof buffer, error);
    if (status == LK_OK && !(*created = strdup(buffer))) {
        rmdir(buffer);
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", path);
    }
    return status;
}

static lk_status set_error(lk_error *error, const char *shown, const char *what)
{
    return lk_error_set(error, LK_ERR_IO, "%s: %s: %s", shown, what, strerror(errno));
}

/* Resolves OUTDIR's parent (OUTDIR itself too when it exists: a symbolic link
 * to a folder keeps pointing at the folder that gets the new set), checks
 * that OUTDIR may be replaced, and creates the hidden folder beside it. */
static lk_status set_open(output_set *set, const char *outdir, lk_error *error)
{
    memset(set, 0, sizeof *set);
    set->shown = outdir;
    size_t length = strlen(outdir);
    char *given = strdup(outdir);
    if (!given) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", outdir);
    while (length > 1 && given[length - 1] == '/') given[--length] = '\0';
    set->path = realpath(given, NULL);
    int cause = set->path ? 0 : errno;
    if (cause == ENOENT) {
        /* a new OUTDIR: its parent must exist (it is not created) */
        char *slash = strrchr(given, '/');
        const char *name = slash ? slash + 1 : given;
        char *parent = slash ? (slash == given ? strdup("/") : strndup(given, (size_t)(slash - given))) : strdup(".");
        char *real_parent = parent ? realpath(parent, NULL) : NULL;
        cause = real_parent ? 0 : parent ? errno : ENOMEM;
        if (real_parent && (!strcmp(name, ".") || !strcmp(name, "..")))
            cause = ENOENT;
        else if (real_parent && !(set->path = malloc(strlen(real_parent) + strlen(name) + 2)))
            cause = ENOMEM;
        else if (real_parent)
            sprintf(set->path, "%s%s%s", real_parent, strcmp(real_parent, "/") ? "/" : "", name);
        free(parent);
        free(real_parent);
    }
    free(given);
    if (!set->path)
        return lk_error_set(error, LK_ERR_IO, "%s: cannot create the directory: %s", outdir, strerror(cause));
    if (!strcmp(set->path, "/")) return lk_error_set(error, LK_ERR_IO, "%s: is the root folder", outdir);
    lk_status status = set_check_owned(set->path, outdir, error);
    if (status == LK_OK && (status = folder_create(set->path, "tmp", &set->build, error)) != LK_OK) {
        error_replace(error, set->path, outdir);
        size_t used = strlen(error->message);
        snprintf(error->message + used, sizeof error->message - used, " (the new set is built beside %s)", outdir);
    }
    /* A folder on another file system than its parent (a mount point) can
     * be written into but not renamed: say so now, not after the work. */
    struct stat outdir_info, build_info;
    if (status == LK_OK && lstat(set->path, &outdir_info) == 0 && stat(set->build, &build_info) == 0 &&
        outdir_info.st_dev != build_info.st_dev)
        status = lk_error_set(error, LK_ERR_IO,
                              "%s: is a mount point: animate replaces the whole folder, which "
                              "cannot be renamed; use a folder inside it",
                              outdir);
    return status;
}

/* Remembers NAME as a file of the set and writes into `path` where to write it. */
static int set_add(output_set *set, const char *name, char *path, size_t size)
{
    if (set->count == set->capacity) {
        size_t capacity = set->capacity ? 2 * set->capacity : 16;
        char **names = realloc(set->names, capacity * sizeof *names);
        if (!names) return 0;
        set->names = names;
        set->capacity = capacity;
    }
    if (!set_name_valid(name, strlen(name)) || snprintf(path, size, "%s/%s", set->build, name) >= (int)size) return 0;
    if (!(set->names[set->count] = strdup(name))) return 0;
    set->count++;
    return 1;
}

static int fsync_folder(const char *folder)
{
    int fd = open(folder, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return -1;
    int result = fsync(fd);
    close(fd);
    return result;
}

static int exchange_folders(const char *a, const char *b)
{
#ifdef RENAME_EXCHANGE
    return renameat2(AT_FDCWD, a, AT_FDCWD, b, RENAME_EXCHANGE);
#else
    (void)a, (void)b;
    errno = ENOSYS;
    return -1;
#endif
}

/* Replaces OUTDIR (locked, holding an animate set or nothing) with the new
 * set; *previous gets where the previous set went. 0: done; 1: another run's
 * set took OUTDIR's name meanwhile, try again; -1: error, OUTDIR as it was. */
enum { SWAP_DONE = 0, SWAP_AGAIN = 1, SWAP_FAILED = -1 };
static int set_swap(output_set *set, char **previous, lk_error *error)
{
    if (exchange_folders(set->build, set->path) == 0) {
        *previous = set->build;
        set->build = NULL;
        return SWAP_DONE;
    }
    if (errno != EINVAL && errno != ENOSYS) {
        set_error(error, set->shown, "cannot swap the new set into place");
        return SWAP_FAILED;
    }
    /* No exchange here: move OUTDIR aside (onto an empty folder of a fresh
     * name, which rename replaces), then the new set in. */
    char *aside;
    if (folder_create(set->path, "old", &aside, error) != LK_OK) return SWAP_FAILED;
    if (rename(set->path, aside) != 0) {
        set_error(error, set->shown, "cannot move the previous set aside");
        rmdir(aside);
        free(aside);
        return SWAP_FAILED;
    }
    if (rename(set->build, set->path) != 0) {
        int cause = errno;
        int result = SWAP_FAILED;
        if (rename(aside, set->path) == 0) {
            errno = cause;
            set_error(error, set->shown, "cannot rename the new set into place");
        } else if (cause == EEXIST || cause == ENOTEMPTY) {
            /* Another run's set took the name meanwhile (a run that found
             * no OUTDIR does not lock): it replaced the same previous set,
             * which can go; ours goes in on the next round. */
            set_delete_folder(aside, set->shown);
            result = SWAP_AGAIN;
        } else {
            lk_error_set(error, LK_ERR_IO, "%s: cannot rename the new set into place: %s; the previous set is in %s",
                         set->shown, strerror(cause), aside);
        }
        free(aside);
        return result;
    }
    *previous = aside;
    return SWAP_DONE;
}

/* Writes the manifest and swaps the new set in (see above). */
static lk_status set_commit(output_set *set, int quiet, lk_error *error)
{
    char path[4096];
    if (snprintf(path, sizeof path, "%s/%s", set->build, SET_MANIFEST) >= (int)sizeof path)
        return lk_error_set(error, LK_ERR_IO, "%s: path too long", set->shown);
    lk_output *manifest;
    lk_status status = lk_output_open(path, &manifest, error);
    if (status != LK_OK) return status;
    fputs(SET_MANIFEST_HEADER, lk_output_stream(manifest));
    for (size_t i = 0; i < set->count; i++) fprintf(lk_output_stream(manifest), "%s\n", set->names[i]);
    if ((status = lk_output_commit(manifest, error)) != LK_OK) return status;
    /* the entries on disk first, then the rename that publishes them (as
     * lk_output_commit does for a file) */
    if (fsync_folder(set->build) != 0) return set_error(error, set->shown, "cannot sync the new set");

    int waited = 0;
    for (int round = 0; round < 100; round++) {
        int locked_fd = open(set->path, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
        if (locked_fd < 0) {
            if (errno != ENOENT) return set_error(error, set->shown, "cannot open");
            /* No OUTDIR: the set takes the name in one rename, which fails
             * if another run's set got there first (then: the next round). */
            if (rename(set->build, set->path) == 0) {
                free(set->build);
                set->build = NULL;
                return LK_OK;
            }
            if (errno == EEXIST || errno == ENOTEMPTY) continue;
            return set_error(error, set->shown, "cannot rename the new set into place");
        }
        if (flock(locked_fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK) {
            if (!quiet && !waited)
                fprintf(stderr, "lodkit animate: waiting for another lodkit animate writing %s\n", set->shown);
            waited = 1;
            while (flock(locked_fd, LOCK_EX) != 0 && errno == EINTR) continue;
        }
        struct stat locked, current;
        if (fstat(locked_fd, &locked) != 0 || lstat(set->path, &current) != 0 || locked.st_dev != current.st_dev ||
            locked.st_ino != current.st_ino) {
            close(locked_fd); /* swapped by the run we waited for: lock the new one */
            continue;
        }
        char *previous = NULL;
        int swap = SWAP_FAILED;
        status = set_check_owned(set->path, set->shown, error);
        if (status == LK_OK) {
            chmod(set->build, locked.st_mode & 07777); /* the folder keeps its permissions */
            swap = set_swap(set, &previous, error);
        }
        close(locked_fd);
        if (swap == SWAP_AGAIN) continue;
        if (swap == SWAP_FAILED) return status != LK_OK ? status : LK_ERR_IO;
        set_delete_folder(previous, set->shown);
        free(previous);
        return LK_OK;
    }
    return lk_error_set(error, LK_ERR_IO, "%s: changed 100 times while the new set was swapped in", set->shown);
}

/* Deletes the new set if it was not swapped in, and frees everything. */
static void set_close(output_set *set)
{
    if (set->build) {
        int directory_fd = open(set->build, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
        if (directory_fd >= 0) {
            for (size_t i = 0; i < set->count; i++) unlinkat(directory_fd, set->names[i], 0);
            unlinkat(directory_fd, SET_MANIFEST, 0);
            close(directory_fd);
        }
        if (rmdir(set->build) != 0 && errno != ENOENT)
            fprintf(stderr, "lodkit animate: left %s behind (%s; safe to delete)\n", set->build, strerror(errno));
    }
    for (size_t i = 0; i < set->count; i++) free(set->names[i]);
    free(set->names);
    free(set->build);
    free(set->path);
    memset(set, 0, sizeof *set);
}

/* The writers name the file they write, inside the hidden folder: name it
 * in OUTDIR, where the user looks for it. Messages of the simplifier and
 * metro name the input. */
static void print_set_error(const output_set *set, const char *input, lk_error *error)
{
    if (set->build) error_replace(error, set->build, set->shown);
    print_error_for(input, set->shown, error);
}

/* lk_animation_metro's progress over the frames of one level, as part of
 * the bar over all levels. */
typedef struct level_progress {
    progress_state *bar;
    size_t level, level_count;
} level_progress;

static int metro_progress(void *user, double fraction, const char *stage)
{
    const level_progress *p = user;
    return progress_draw(p->bar, ((double)p->level + fraction) / (double)p->level_count, stage);
}

static int parse_schemes(const char *text, lk_anim_scheme *schemes, size_t *count)
{
    *count = 0;
    if (!strcmp(text, "all")) {
        schemes[0] = LK_ANIM_SCHEME_MAX, schemes[1] = LK_ANIM_SCHEME_AVG, schemes[2] = LK_ANIM_SCHEME_FRAME;
        *count = 3;
        return 1;
    }
    char buffer[64];
    snprintf(buffer, sizeof buffer, "%s", text);
    for (char *token = strtok(buffer, ","); token; token = strtok(NULL, ",")) {
        lk_anim_scheme scheme;
        if (lk_anim_scheme_parse(token, &scheme) != 0 || *count == 3) return 0;
        for (size_t i = 0; i < *count; i++)
            if (schemes[i] == scheme) return 0;
        schemes[(*count)++] = scheme;
    }
    return *count > 0;
}

static void scheme_label(lk_anim_scheme scheme, size_t frame, char *out, size_t size)
{
    if (scheme == LK_ANIM_SCHEME_FRAME)
        snprintf(out, size, "frame%zu", frame);
    else
        snprintf(out, size, "%s", lk_anim_scheme_name(scheme));
}

static lk_status write_csv(const char *path, const double *ratios, size_t level_count, const size_t *frames,
                           size_t frame_count, const lk_anim_simplify_result *results, const lk_metro_result *metro,
                           double diagonal, lk_error *error)
{
    lk_output *file;
    lk_status status = lk_output_open(path, &file, error);
    if (status != LK_OK) return status;
    FILE *csv = lk_output_stream(file);
    fprintf(csv, "level,ratio,frame,triangles,mean,rms,max,rms_forward,rms_backward,rms_percent\n");
    for (size_t l = 0; l < level_count; l++)
        for (size_t k = 0; k < frame_count; k++) {
            const lk_metro_result *m = &metro[l * frame_count + k];
            double mean = fmax(m->forward.mean, m->backward.mean), rms = fmax(m->forward.rms, m->backward.rms);
            fprintf(csv, "%zu,%.4g,%zu,%zu,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", l + 1, ratios[l], frames[k],
                    results[l].animation.mesh.triangle_count, mean, rms, m->hausdorff, m->forward.rms, m->backward.rms,
                    diagonal > 0 ? 100 * rms / diagonal : 0);
        }
    return lk_output_commit(file, error);
}

int cmd_animate(int argc, char **argv)
{
    lk_anim_scheme schemes[3] = {LK_ANIM_SCHEME_MAX};
    size_t scheme_count = 1, frame = 0, level_count = 10, metro_step = 1, samples = 10;
    double ratio = 0, lost_surface = LK_ANIM_LOST_SURFACE_DEFAULT;
    int strict = 0, keep_seams = 0, no_metro = 0;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_ANIMATE, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_SCHEME:
            if (!parse_schemes(arg, schemes, &scheme_count))
                return usage_error("animate", "--scheme: '%s' is not max, avg, frame, a comma list of them or all",
                                   arg);
            break;
        case OPT_FRAME:
            if (!parse_size_option(arg, &frame))
                return usage_error("animate", "--frame: '%s' is not a frame number", arg);
            break;
        case OPT_LEVELS:
            if (!parse_size_option(arg, &level_count) || level_count < 1 || level_count > 1000)
                return usage_error("animate", "--levels: '%s' is not a number of levels in 1..1000", arg);
            break;
        case OPT_RATIO:
            if (!parse_double_option(arg, &ratio) || !(ratio > 0 && ratio <= 1))
                return usage_error("animate", "--ratio: '%s' is not a number in (0, 1]", arg);
            break;
        case OPT_STRICT: strict = 1; break;
        case OPT_KEEP_SEAMS: keep_seams = 1; break;
        case OPT_METRO_STEP:
            if (!parse_size_option(arg, &metro_step) || metro_step < 1)
                return usage_error("animate", "--metro-step: '%s' is not a positive integer", arg);
            break;
        case OPT_SAMPLES_PER_FACE:
            if (!parse_size_option(arg, &samples) || samples < 1 || samples > 100000)
                return usage_error("animate", "--samples-per-face: '%s' is not a number in 1..100000", arg);
            break;
        case OPT_LOST_SURFACE:
            if (!parse_double_option(arg, &lost_surface) || !(lost_surface >= 0 && lost_surface <= 1e12))
                return usage_error("animate", "--lost-surface: '%s' is not a weight in [0, 1e12]", arg);
            break;
        case OPT_NO_METRO: no_metro = 1; break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("animate", "%s", "expected IN and OUTDIR");
    const char *input = argv[optind], *outdir = argv[optind + 1];
    if (ratio > 0) level_count = 1;

    lk_error error = {0};
    lk_animation original;
    lk_animation_init(&original);
    lk_animation_read_options read_options;
    memset(&read_options, 0, sizeof read_options);
    read_options.max_bytes = cli_max_memory;
    if (lk_animation_read_ex(input, &read_options, &original, NULL, &error) != LK_OK) {
        print_error_for(input, NULL, &error);
        return EXIT_BAD_INPUT;
    }
    for (size_t i = 0; i < scheme_count; i++)
        if (schemes[i] == LK_ANIM_SCHEME_FRAME && frame >= original.frame_count) {
            fprintf(stderr, "lodkit animate: --frame %zu: %s has %s\n", frame, input,
                    count_noun(original.frame_count, "frame", "frames"));
            lk_animation_free(&original);
            return EXIT_USAGE;
        }
    char stem[200];
    path_stem(input, stem, sizeof stem);
    if (strchr(stem, '\n')) {
        fprintf(stderr, "lodkit animate: %s: a name with a line break cannot be listed in the output set\n", input);
        lk_animation_free(&original);
        return EXIT_BAD_INPUT;
    }
    output_set set;
    if (set_open(&set, outdir, &error) != LK_OK) {
        print_error(&error);
        set_close(&set);
        lk_animation_free(&original);
        return EXIT_BAD_INPUT;
    }
    const char *extension = output_extension(input);

    double *ratios = malloc_array(level_count, sizeof(double));
    size_t frame_count = (original.frame_count + metro_step - 1) / metro_step;
    size_t *frames = malloc_array(frame_count, sizeof(size_t));
    lk_anim_simplify_result *results = calloc_array(scheme_count * level_count, sizeof *results);
    lk_metro_result *metro =
        no_metro ? NULL : malloc_array(scheme_count * level_count * frame_count, sizeof(lk_metro_result));
    double *values = no_metro ? NULL : malloc_array(scheme_count * level_count * frame_count, sizeof(double));
    level_summary *summaries = calloc_array(scheme_count * level_count, sizeof *summaries);
    int exit_code = EXIT_OK;
    if (!ratios || !frames || !results || (!no_metro && (!metro || !values)) || !summaries) {
        lk_error_set(&error, LK_ERR_NOMEM, "out of memory for %zu levels x %zu frames", level_count, frame_count);
        print_error(&error);
        exit_code = EXIT_BAD_INPUT;
        goto done;
    }
    for (size_t l = 0; l < level_count; l++) ratios[l] = ratio > 0 ? ratio : (double)(l + 1) / (double)level_count;
    for (size_t k = 0; k < frame_count; k++) frames[k] = k * metro_step;

    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    metro_options.samples_per_face = (double)samples;
    double diagonal = 0;
    for (size_t i = 0; i < scheme_count && exit_code == EXIT_OK; i++) {
        char label[64], path[4096];
        scheme_label(schemes[i], frame, label, sizeof label);
        lk_anim_simplify_options simplify_options;
        lk_anim_simplify_options_default(&simplify_options);
        simplify_options.scheme = schemes[i];
        simplify_options.frame = frame;
        simplify_options.allow_folds = !strict;
        simplify_options.keep_seams = keep_seams;
        simplify_options.lost_surface = lost_surface;
        progress_state progress;
        progress_init(&progress, quiet || json, label);
        lk_anim_simplify_result *level_results = results + i * level_count;
        progress_draw(&progress, 0, "simplify"); /* at once, whatever the library reports */
        lk_status status = lk_animation_simplify_levels(&original, &simplify_options, ratios, level_count,
                                                        level_results, progress_draw, &progress, &error);
        progress_done(&progress);
        for (size_t l = 0; l < level_count && status == LK_OK; l++) {
            char name[512];
            if (ratio > 0)
                snprintf(name, sizeof name, "%s-%s.%s", stem, label, extension);
            else
                snprintf(name, sizeof name, "%s-%s-L%02zu.%s", stem, label, l + 1, extension);
            if (!set_add(&set, name, path, sizeof path))
                status = lk_error_set(&error, LK_ERR_NOMEM, "%s/%s: path too long or out of memory", outdir, name);
            else
                status = lk_animation_write(path, &level_results[l].animation, &error);
            level_summary *summary = &summaries[i * level_count + l];
            summary->triangles = level_results[l].animation.mesh.triangle_count;
            summary->folds_from = level_results[l].folds_from_triangles;
            diagonal = level_results[l].diagonal;
        }
        if (status == LK_OK && !no_metro) {
            progress_init(&progress, quiet || json, "metro");
            for (size_t l = 0; l < level_count && status == LK_OK; l++) {
                lk_metro_result *rows = metro + (i * level_count + l) * frame_count;
                level_progress per_level = {&progress, l, level_count};
                status = lk_animation_metro(&level_results[l].animation, &original, frames, frame_count, &metro_options,
                                            rows, metro_progress, &per_level, &error);
                level_summary *summary = &summaries[i * level_count + l];
                for (size_t k = 0; k < frame_count && status == LK_OK; k++) {
                    double rms = fmax(rows[k].forward.rms, rows[k].backward.rms);
                    double percent = diagonal > 0 ? 100 * rms / diagonal : 0;
                    values[(i * level_count + l) * frame_count + k] = percent;
                    if (k == 0 || percent > summary->worst_rms)
                        summary->worst_rms = percent, summary->worst_frame = frames[k];
                    summary->mean_rms += percent / (double)frame_count;
                }
                progress_draw(&progress, (double)(l + 1) / (double)level_count, "metro");
            }
            progress_done(&progress);
            char name[512];
            snprintf(name, sizeof name, "%s-%s.csv", stem, label);
            if (status == LK_OK && !set_add(&set, name, path, sizeof path))
                status = lk_error_set(&error, LK_ERR_NOMEM, "%s/%s: path too long or out of memory", outdir, name);
            if (status == LK_OK)
                status = write_csv(path, ratios, level_count, frames, frame_count, level_results,
                                   metro + i * level_count * frame_count, diagonal, &error);
        }
        if (status != LK_OK) {
            print_set_error(&set, input, &error);
            exit_code = EXIT_BAD_INPUT;
        }
    }
    /* heat maps on one colour scale */
    if (exit_code == EXIT_OK && !no_metro) {
        double low = INFINITY, high = 0;
        for (size_t i = 0; i < scheme_count * level_count * frame_count; i++)
            if (values[i] > 0) low = fmin(low, values[i]), high = fmax(high, values[i]);
        for (size_t i = 0; i < scheme_count && exit_code == EXIT_OK; i++) {
            char label[64], title[512], path[4096];
            scheme_label(schemes[i], frame, label, sizeof label);
            snprintf(title, sizeof title, "%s, scheme %s: RMS distance to the original frame", stem, label);
            unsigned char *rgba = NULL;
            unsigned width = 0, height = 0;
            /* three decades at most: rounding noise (1e-16 at 100%) must not stretch the scale */
            double scale_low = isfinite(low) ? fmax(low, high * 1e-3) : 0;
            lk_status status =
                lk_anim_error_map(values + i * level_count * frame_count, level_count, frame_count, ratios, frames,
                                  scale_low, high, title, "RMS %", &rgba, &width, &height, &error);
            char name[512];
            snprintf(name, sizeof name, "%s-%s-rms.png", stem, label);
            if (status == LK_OK && !set_add(&set, name, path, sizeof path))
                status = lk_error_set(&error, LK_ERR_NOMEM, "%s/%s: path too long or out of memory", outdir, name);
            if (status == LK_OK) status = lk_image_write_png(path, rgba, width, height, &error);
            lk_free(rgba);
            if (status != LK_OK) {
                print_set_error(&set, input, &error);
                exit_code = EXIT_BAD_INPUT;
            }
        }
    }
    if (exit_code == EXIT_OK && set_commit(&set, quiet, &error) != LK_OK) {
        print_set_error(&set, input, &error);
        exit_code = EXIT_BAD_INPUT;
    }
    if (exit_code == EXIT_OK && json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", input);
        cJSON_AddNumberToObject(root, "vertices", (double)original.mesh.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)original.mesh.triangle_count);
        cJSON_AddNumberToObject(root, "frames", (double)original.frame_count);
        cJSON_AddNumberToObject(root, "diagonal", diagonal);
        cJSON *list = cJSON_AddArrayToObject(root, "schemes");
        for (size_t i = 0; i < scheme_count; i++) {
            char label[64];
            scheme_label(schemes[i], frame, label, sizeof label);
            cJSON *entry = cJSON_CreateObject();
            cJSON_AddStringToObject(entry, "scheme", label);
            cJSON_AddNumberToObject(entry, "seconds", results[i * level_count + 0].seconds);
            cJSON_AddNumberToObject(entry, "working_bytes", (double)results[i * level_count].working_bytes);
            cJSON *levels = cJSON_AddArrayToObject(entry, "levels");
            for (size_t l = 0; l < level_count; l++) {
                const level_summary *summary = &summaries[i * level_count + l];
                cJSON *level = cJSON_CreateObject();
                cJSON_AddNumberToObject(level, "ratio", ratios[l]);
                cJSON_AddNumberToObject(level, "triangles", (double)summary->triangles);
                cJSON_AddBoolToObject(level, "target_reached", results[i * level_count + l].target_reached);
                cJSON_AddNumberToObject(level, "folds_from_triangles", (double)summary->folds_from);
                if (!no_metro) {
                    cJSON_AddNumberToObject(level, "worst_rms_percent", summary->worst_rms);
                    cJSON_AddNumberToObject(level, "worst_frame", (double)summary->worst_frame);
                    cJSON_AddNumberToObject(level, "mean_rms_percent", summary->mean_rms);
                }
                cJSON_AddItemToArray(levels, level);
            }
            cJSON_AddItemToArray(list, entry);
        }
        print_json(root);
    } else if (exit_code == EXIT_OK && !quiet) {
        printf("%s: %s, %s, %s; diagonal %.6g\n", input, n_vertices(original.mesh.vertex_count),
               n_triangles(original.mesh.triangle_count), count_noun(original.frame_count, "frame", "frames"),
               diagonal);
        for (size_t i = 0; i < scheme_count; i++) {
            char label[64];
            scheme_label(schemes[i], frame, label, sizeof label);
            const lk_anim_simplify_result *last = &results[i * level_count + level_count - 1];
            printf("\nscheme %s: %.3f s for %s, %s bytes of per-frame quadrics\n", label, last->seconds,
                   count_noun(level_count, "level", "levels"), thousands(last->working_bytes));
            printf("| level | kept | triangles | worst-frame RMS %% | (frame) | mean RMS %% | note |\n");
            printf("|---:|---:|---:|---:|---:|---:|---|\n");
            for (size_t l = 0; l < level_count; l++) {
                const level_summary *summary = &summaries[i * level_count + l];
                const lk_anim_simplify_result *result = &results[i * level_count + l];
                char note[96] = "";
                if (!result->target_reached)
                    snprintf(note, sizeof note, "target not reached (folds)");
                else if (summary->folds_from)
                    snprintf(note, sizeof note, "folds allowed below %zu triangles", summary->folds_from);
                if (no_metro)
                    printf("| %zu | %g%% | %zu | - | - | - | %s |\n", l + 1, 100 * ratios[l], summary->triangles, note);
                else
                    printf("| %zu | %g%% | %zu | %.4f | %zu | %.4f | %s |\n", l + 1, 100 * ratios[l],
                           summary->triangles, summary->worst_rms, summary->worst_frame, summary->mean_rms, note);
            }
        }
    }
done:
    set_close(&set);
    if (results)
        for (size_t i = 0; i < scheme_count * level_count; i++) lk_anim_simplify_result_free(&results[i]);
    free(results), free(ratios), free(frames), free(metro), free(values), free(summaries);
    lk_animation_free(&original);
    return exit_code;
}
