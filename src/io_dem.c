/* SPDX-License-Identifier: MIT */
/* Elevation grids: lk_dem_read (PGM and PNG heightmaps with our own readers,
 * everything else through GDAL), no-data filling and bilinear resampling.
 *
 * Conventions (see include/lodkit.h, "Elevation grids"):
 *   - heights[j * width + i] stands at x = origin_x + i * spacing_x,
 *     y = origin_y + j * spacing_y; y grows northwards, so north-up rasters
 *     (and images, whose top row is taken as north) are flipped on reading;
 *   - geographic grids (degrees) get metre spacings from the WGS84 ellipsoid
 *     at the grid's mean latitude (an equirectangular projection centred
 *     there: distances are exact along the mean parallel; east-west ones
 *     elsewhere are too long by cos(mean latitude) / cos(latitude), and
 *     north-south ones are off by under 1%, the meridian degree growing
 *     from 110.57 km at the equator to 111.69 km at the poles);
 *   - no-data samples (the band's no-data value, NaN, +-Inf; transparent
 *     PNG pixels) are replaced by the height of the nearest valid sample;
 *   - PGM/PNG heights are sample / maxval * image_height_range * z_scale,
 *     spaced options->spacing apart with the origin at 0, 0; colour PNGs
 *     are read only when every pixel is grey (r = g = b);
 *   - grids are at least 2x2 (a surface needs four corners).
 *   - NumPy .npz archives (matplotlib's sample DEMs): the 2-D array
 *     "elevation", first row north, spaced dx/dy from xmin/ymin;
 * Dispatch: PGM/PNG by magic bytes or by the .pgm/.png extension, .npz by
 * its extension, everything else through GDAL. */
#include "bytes.h"
#include "internal.h"
#include "io_dem_gdal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <png.h>
#include <zlib.h>

#define LK_DEM_DEFAULT_MAX_SAMPLES ((size_t)1 << 26)
#define LK_DEM_PI 3.14159265358979323846

void lk_dem_options_default(lk_dem_options *options)
{
    if (!options) return;
    memset(options, 0, sizeof *options);
    options->band = 1;
    options->z_scale = 1.0;
    options->spacing = 1.0;
    options->image_height_range = 1000.0;
    options->max_samples = LK_DEM_DEFAULT_MAX_SAMPLES;
}

static const char *base_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

static lk_status check_options(const lk_dem_options *options, lk_error *error)
{
    if (options->band < 1) return lk_error_set(error, LK_ERR_INVALID, "dem: band must be >= 1 (got %d)", options->band);
    if (!isfinite(options->z_scale))
        return lk_error_set(error, LK_ERR_INVALID, "dem: z_scale must be finite (got %g)", options->z_scale);
    if (!(options->spacing > 0.0) || !isfinite(options->spacing))
        return lk_error_set(error, LK_ERR_INVALID, "dem: spacing must be a positive finite number (got %g)",
                            options->spacing);
    if (!isfinite(options->image_height_range))
        return lk_error_set(error, LK_ERR_INVALID, "dem: image_height_range must be finite (got %g)",
                            options->image_height_range);
    if (options->max_samples == 0) return lk_error_set(error, LK_ERR_INVALID, "dem: max_samples must be > 0");
    return LK_OK;
}

/* Everything a read holds at once (the file, the grid, the no-data fill,
 * decoded PNG rows, inflated .npz members) is charged to one budget of
 * max_samples x LK_DEM_BYTES_PER_SAMPLE bytes, the budget max_samples is
 * derived from (lodkit.h). GDAL's own block cache is not counted. */
static lk__budget dem_budget(const lk_dem_options *options)
{
    lk__budget budget = {options->max_samples > SIZE_MAX / LK_DEM_BYTES_PER_SAMPLE
                             ? SIZE_MAX
                             : options->max_samples * LK_DEM_BYTES_PER_SAMPLE,
                         0};
    return budget;
}

/* Charges `count` items of `size` bytes for a width x height grid. */
static lk_status dem_charge(lk__budget *budget, size_t count, size_t size, const char *name, size_t width,
                            size_t height, lk_error *error)
{
    if (lk__budget_charge(budget, count, size)) return LK_OK;
    return lk_error_set(error, LK_ERR_LIMIT,
                        "%s: reading the %zux%zu grid needs more than %zu bytes (max_samples x %u bytes per sample)",
                        name, width, height, budget->limit, LK_DEM_BYTES_PER_SAMPLE);
}

/* Refuses a grid before anything of its size is allocated. */
static lk_status check_size(const char *name, size_t width, size_t height, size_t max_samples, lk_error *error)
{
    if (width < 2 || height < 2)
        return lk_error_set(error, LK_ERR_RANGE,
                            "%s: a %zux%zu grid is too small (a heightfield needs at least 2x2 samples)", name, width,
                            height);
    if (width > max_samples / height)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: %zux%zu grid (%.0f samples) exceeds the budget of %zu samples (max_samples)", name,
                            width, height, (double)width * (double)height, max_samples);
    return LK_OK;
}

/* ---- no-data filling ---------------------------------------------------- */

/* Nearest-valid-sample fill with a two-pass propagation (the vector distance
 * transform idea): every cell keeps the index of the nearest valid sample
 * found so far; a forward raster pass looks at the four already visited
 * neighbours, a backward pass at the four others. Distances are measured in
 * metres (spacing_x, spacing_y) so that anisotropic grids fill sensibly. The
 * two passes give the exact nearest sample except in rare configurations
 * where the true nearest is reached only through a cell that prefers a
 * different one; the result is always a valid height from the grid and is
 * deterministic. `valid` marks the cells that hold data. */
static lk_status fill_nodata(lk_heightfield *field, const unsigned char *valid, lk__budget *budget, const char *name,
                             lk_error *error)
{
    size_t width = field->width, height = field->height, count = width * height;
    size_t valid_count = 0;
    for (size_t k = 0; k < count; k++) valid_count += valid[k] != 0;
    if (valid_count == 0)
        return lk_error_set(error, LK_ERR_RANGE, "%s: no valid heights (every sample is no-data)", name);
    field->nodata_count = count - valid_count;
    if (valid_count == count) return LK_OK;

    const size_t none = SIZE_MAX;
    lk_status status = dem_charge(budget, count, sizeof(size_t), name, width, height, error);
    if (status != LK_OK) return status;
    size_t *nearest = lk__malloc_array(count, sizeof *nearest);
    if (!nearest)
        return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for the no-data fill (%zu samples)", name, count);
    for (size_t k = 0; k < count; k++) nearest[k] = valid[k] ? k : none;

    double sx2 = field->spacing_x * field->spacing_x, sy2 = field->spacing_y * field->spacing_y;
#define LK_DEM_DIST2(cell_i, cell_j, seed)                                                                             \
    (sx2 * ((double)(cell_i) - (double)((seed) % width)) * ((double)(cell_i) - (double)((seed) % width)) +             \
     sy2 * ((double)(cell_j) - (double)((seed) / width)) * ((double)(cell_j) - (double)((seed) / width)))
    /* Offsets (di, dj) of the neighbours visited before a cell in each pass. */
    static const int forward[4][2] = {{-1, 0}, {-1, -1}, {0, -1}, {1, -1}};
    for (int pass = 0; pass < 2; pass++) {
        for (size_t step = 0; step < count; step++) {
            size_t k = pass == 0 ? step : count - 1 - step;
            if (valid[k]) continue;
            size_t i = k % width, j = k / width;
            size_t best = nearest[k];
            double best_d2 = best == none ? INFINITY : LK_DEM_DIST2(i, j, best);
            for (int n = 0; n < 4; n++) {
                long di = pass == 0 ? forward[n][0] : -forward[n][0];
                long dj = pass == 0 ? forward[n][1] : -forward[n][1];
                long ni = (long)i + di, nj = (long)j + dj;
                if (ni < 0 || nj < 0 || ni >= (long)width || nj >= (long)height) continue;
                size_t seed = nearest[(size_t)nj * width + (size_t)ni];
                if (seed == none) continue;
                double d2 = LK_DEM_DIST2(i, j, seed);
                /* Ties go to the smaller index so the result is order-free. */
                if (d2 < best_d2 || (d2 == best_d2 && seed < best)) {
                    best = seed;
                    best_d2 = d2;
                }
            }
            nearest[k] = best;
        }
    }
#undef LK_DEM_DIST2
    /* After both passes every cell has a seed: the forward pass carries
     * seeds down and right, the backward pass up and left, and a valid cell
     * exists. */
    for (size_t k = 0; k < count; k++)
        if (!valid[k]) field->heights[k] = field->heights[nearest[k]];
    free(nearest);
    lk__budget_release(budget, count, sizeof(size_t));
    return LK_OK;
}

/* Marks the valid samples, fills the others and computes the range; frees
 * the field on failure. */
static lk_status finish_field(lk_heightfield *field, unsigned char *valid, lk__budget *budget, const char *name,
                              lk_error *error)
{
    lk_status status = fill_nodata(field, valid, budget, name, error);
    free(valid);
    lk__budget_release(budget, field->width * field->height, 1);
    if (status != LK_OK) {
        lk_heightfield_free(field);
        return status;
    }
    lk__heightfield_compute_range(field);
    return LK_OK;
}

/* ---- GDAL --------------------------------------------------------------- */

/* options->progress at `fraction` of the read; non-zero: the caller cancels. */
static int dem_progress(const lk_dem_options *options, double fraction, const char *stage)
{
    return options->progress ? options->progress(options->progress_user, fraction, stage) : 0;
}

/* GDAL's progress of the raster read, as 5% .. 85% of the whole. */
static int CPL_STDCALL gdal_progress(double complete, const char *message, void *user)
{
    (void)message;
    return !dem_progress(user, 0.05 + 0.8 * complete, "reading"); /* GDAL goes on while TRUE */
}

/* Metres per degree of longitude and of latitude on the WGS84 ellipsoid at
 * latitude `lat_deg` (radii of curvature in the prime vertical and in the
 * meridian). At the equator: 111319.5 and 110574.3 m. */
static void metres_per_degree(double lat_deg, double *per_lon, double *per_lat)
{
    const double a = 6378137.0, f = 1.0 / 298.257223563;
    const double e2 = f * (2.0 - f);
    double phi = lat_deg * (LK_DEM_PI / 180.0);
    double s = sin(phi);
    double w = sqrt(1.0 - e2 * s * s);
    *per_lon = (LK_DEM_PI / 180.0) * a * cos(phi) / w;
    *per_lat = (LK_DEM_PI / 180.0) * a * (1.0 - e2) / (w * w * w);
}

/* Places a grid whose south-west sample centre is (first_x, first_y) with
 * steps (step_x, step_y) in CRS units; geographic grids (degrees) get metres
 * at the grid's mean latitude. */
static lk_status set_georeference(lk_heightfield *out, double first_x, double first_y, double step_x, double step_y,
                                  int geographic, const char *name, lk_error *error)
{
    if (!geographic) {
        out->spacing_x = step_x;
        out->spacing_y = step_y;
        out->origin_x = first_x;
        out->origin_y = first_y;
        return LK_OK;
    }
    double mean_lat = fmin(90.0, fmax(-90.0, first_y + 0.5 * step_y * (double)(out->height - 1)));
    double per_lon, per_lat;
    metres_per_degree(mean_lat, &per_lon, &per_lat);
    if (!(per_lon * step_x > 0.0))
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: geographic grid centred on a pole (mean latitude %g): no east-west scale", name,
                            mean_lat);
    out->spacing_x = step_x * per_lon;
    out->spacing_y = step_y * per_lat;
    out->origin_x = first_x * per_lon;
    out->origin_y = first_y * per_lat;
    return LK_OK;
}

/* Vertical unit of the band -> metres factor (1 when unknown or metres). */
static double unit_factor(const char *unit)
{
    if (!unit || !unit[0]) return 1.0;
    static const char *const feet[] = {"ft", "feet", "foot", "international foot", "international feet"};
    static const char *const us_feet[] = {"us-ft", "ftus", "us survey foot", "us survey feet", "us_survey_foot"};
    size_t len = strlen(unit);
    for (size_t n = 0; n < sizeof feet / sizeof feet[0]; n++)
        if (strlen(feet[n]) == len && lk__word_equals(unit, len, feet[n])) return 0.3048;
    for (size_t n = 0; n < sizeof us_feet / sizeof us_feet[0]; n++)
        if (strlen(us_feet[n]) == len && lk__word_equals(unit, len, us_feet[n])) return 1200.0 / 3937.0;
    return 1.0;
}

/* CF conventions (netCDF) label longitude/latitude axes with these units;
 * GDAL exposes them as dataset metadata "VAR#units=degrees_east". */
static bool metadata_says_degrees(const lk__gdal_api *gdal, GDALDatasetH dataset)
{
    char **metadata = gdal->GDALGetMetadata(dataset, NULL);
    bool east = false, north = false;
    for (; metadata && *metadata; metadata++) {
        const char *item = *metadata;
        const char *units = strstr(item, "#units=");
        if (!units) continue;
        units += 7;
        if (strncmp(units, "degrees_east", 12) == 0 || strncmp(units, "degree_east", 11) == 0) east = true;
        if (strncmp(units, "degrees_north", 13) == 0 || strncmp(units, "degree_north", 12) == 0) north = true;
    }
    return east && north;
}

/* Decides whether the geotransform is in degrees. A geographic CRS says so;
 * without a CRS, CF "degrees_east/north" axis units say so (netCDF files
 * such as etopo20.cdf carry no CRS); failing both, a grid whose extent lies
 * within longitude [-180, 360] (plus a wrap-around seam column or two) and
 * latitude [-90, 90] with a pixel size below one unit is taken as
 * geographic. The last rule can misread a small metre grid with sub-metre
 * cells and no CRS near the origin; such files should carry a CRS. */
static bool is_geographic(const lk__gdal_api *gdal, GDALDatasetH dataset, const double transform[6], size_t width,
                          size_t height)
{
    OGRSpatialReferenceH srs = gdal->GDALGetSpatialRef(dataset);
    if (srs) return gdal->OSRIsGeographic(srs) != 0;
    if (metadata_says_degrees(gdal, dataset)) return true;
    double dx = fabs(transform[1]), dy = fabs(transform[5]);
    if (!(dx < 1.0 && dy < 1.0)) return false;
    double x0 = transform[0], x1 = transform[0] + transform[1] * (double)width;
    double y0 = transform[3], y1 = transform[3] + transform[5] * (double)height;
    double xmin = fmin(x0, x1), xmax = fmax(x0, x1), ymin = fmin(y0, y1), ymax = fmax(y0, y1);
    return xmin >= -180.0 - dx && xmin <= 360.0 && xmax - xmin <= 360.0 + 2.0 * dx && ymin >= -90.0 - dy &&
           ymax <= 90.0 + dy;
}

/* "NAME: WHAT (GDAL: its last message)": the file named once, by the name
 * lodkit's messages use (a server must not show where its files are).
 * GDAL's own mentions of the path it was given go: quoted (`path',
 * 'path', "path") or leading ("path: "); any other becomes the name. */
static lk_status gdal_error(const lk__gdal_api *gdal, lk_error *error, lk_status status, const char *path,
                            const char *name, const char *what)
{
    const char *message = gdal->CPLGetLastErrorMsg();
    char cleaned[sizeof error->message];
    size_t o = 0, path_length = strlen(path), name_length = strlen(name);
    for (const char *p = message ? message : ""; *p && o + 1 < sizeof cleaned;) {
        if (path_length && strncmp(p, path, path_length) == 0) {
            const char *after = p + path_length;
            bool quoted = o > 0 && strchr("`'\"", cleaned[o - 1]) && *after && strchr("`'\"", *after);
            if (quoted || (o == 0 && *after == ':')) {
                o -= quoted;   /* the opening quote */
                p = after + 1; /* past the closing quote or the colon */
                continue;
            }
            if (o + name_length + 1 < sizeof cleaned) {
                memcpy(cleaned + o, name, name_length);
                o += name_length;
                p = after;
                continue;
            }
        }
        cleaned[o++] = *p++;
    }
    /* Without the spaces around it and its final full stop. */
    while (o && (cleaned[o - 1] == ' ' || cleaned[o - 1] == '\n' || cleaned[o - 1] == '\r')) o--;
    if (o && cleaned[o - 1] == '.') o--;
    cleaned[o] = '\0';
    const char *text = cleaned;
    while (*text == ' ') text++;
    if (!*text) return lk_error_set(error, status, "%s: %s", name, what);
    return lk_error_set(error, status, "%s: %s (GDAL: %s)", name, what, text);
}

/* The GDAL drivers lodkit reads grids with: formats whose samples are all
 * in the one file named. A VRT, or a header naming its data file (ENVI,
 * EHdr, HFA spill files, ...), can point at any file on the machine, so
 * that a grid lying in a served folder would read bytes from elsewhere. */
static const char *const gdal_drivers[] = {
    "GTiff", "netCDF", "AAIGrid", "GRASSASCIIGrid", "SRTMHGT",  "DTED", "USGSDEM", "XYZ",  "GSAG", "GSBG",
    "GS7BG", "BT",     "HF2",     "Terragen",       "Leveller", "ISG",  "SIGDEM",  "ZMap", NULL};

/* GDAL settings of this thread for one read (restored afterwards): no
 * sidecar files either (.aux.xml metadata, .ovr overviews, .msk masks,
 * world files), which may be links leading anywhere. */
typedef struct gdal_setting {
    const char *key, *value;
    char *saved;
    bool had;
} gdal_setting;

static void gdal_settings_apply(const lk__gdal_api *gdal, gdal_setting *settings, size_t count)
{
    for (size_t i = 0; i < count; i++) {
        const char *old = gdal->CPLGetThreadLocalConfigOption(settings[i].key, NULL);
        settings[i].had = old != NULL;
        settings[i].saved = old ? strdup(old) : NULL;
        gdal->CPLSetThreadLocalConfigOption(settings[i].key, settings[i].value);
    }
}

static void gdal_settings_restore(const lk__gdal_api *gdal, gdal_setting *settings, size_t count)
{
    for (size_t i = 0; i < count; i++) {
        gdal->CPLSetThreadLocalConfigOption(settings[i].key, settings[i].had ? settings[i].saved : NULL);
        free(settings[i].saved);
    }
}

/* Reads a grid through GDAL; `name` is for messages. `checked` is the
 * fstat of checked_path as lk__open_input opened it: GDAL opens the path
 * itself, so it must still be that file once GDAL has opened it. */
static lk_status read_gdal(const char *path, const char *name, const char *checked_path, const struct stat *checked,
                           const lk_dem_options *options, lk_heightfield *out, lk_error *error)
{
    const lk__gdal_api *gdal = lk__gdal_api_load(name, error);
    if (!gdal) return LK_ERR_UNSUPPORTED;
    lk__budget budget = dem_budget(options);
    gdal_setting settings[] = {{"GDAL_DISABLE_READDIR_ON_OPEN", "EMPTY_DIR", NULL, false},
                               {"GDAL_PAM_ENABLED", "NO", NULL, false}};
    gdal_settings_apply(gdal, settings, sizeof settings / sizeof settings[0]);
    gdal->CPLPushErrorHandler(gdal->CPLQuietErrorHandler);
    gdal->CPLErrorReset();
    lk_status status = LK_OK;
    unsigned char *valid = NULL;
    GDALDatasetH dataset =
        gdal->GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR, gdal_drivers, NULL, NULL);
    if (!dataset) {
        status = gdal_error(gdal, error, LK_ERR_UNSUPPORTED, path, name, "not a raster format GDAL can read");
        /* Which driver would have read it (looking at its first bytes only)? */
        GDALDriverH driver = gdal->GDALIdentifyDriverEx(path, GDAL_OF_RASTER, NULL, NULL);
        if (driver && gdal->CSLFindString((CSLConstList)gdal_drivers, gdal->GDALGetDriverShortName(driver)) < 0)
            status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                                  "%s: a %s file (GDAL driver %s), whose data can lie in other files; lodkit reads "
                                  "grids held in one file (GeoTIFF, netCDF, ASCII grids, SRTM .hgt, DTED, ...)",
                                  name, gdal->GDALGetDriverLongName(driver), gdal->GDALGetDriverShortName(driver));
        goto done;
    }
    struct stat now;
    if (checked && (stat(checked_path, &now) != 0 || now.st_dev != checked->st_dev || now.st_ino != checked->st_ino)) {
        status = lk_error_set(error, LK_ERR_IO, "%s: the file was replaced while it was opened", name);
        goto done;
    }
    int band_count = gdal->GDALGetRasterCount(dataset);
    if (band_count == 0) {
        char **subdatasets = gdal->GDALGetMetadata(dataset, "SUBDATASETS");
        if (subdatasets && subdatasets[0]) {
            const char *eq = strchr(subdatasets[0], '=');
            status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                                  "%s: no raster band at the top level; it holds subdatasets, e.g. %s", name,
                                  eq ? eq + 1 : subdatasets[0]);
        } else {
            status = lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: the file holds no raster band", name);
        }
        goto done;
    }
    if (options->band > band_count) {
        status = lk_error_set(error, LK_ERR_INVALID, "%s: band %d requested but the file has %d band%s", name,
                              options->band, band_count, band_count == 1 ? "" : "s");
        goto done;
    }
    int x_size = gdal->GDALGetRasterXSize(dataset), y_size = gdal->GDALGetRasterYSize(dataset);
    if (x_size <= 0 || y_size <= 0) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: raster size %dx%d", name, x_size, y_size);
        goto done;
    }
    size_t width = (size_t)x_size, height = (size_t)y_size;
    status = check_size(name, width, height, options->max_samples, error);
    if (status != LK_OK) goto done;

    double transform[6];
    bool georeferenced = gdal->GDALGetGeoTransform(dataset, transform) == CE_None;
    gdal->CPLErrorReset();
    if (georeferenced && (transform[2] != 0.0 || transform[4] != 0.0)) {
        status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                              "%s: rotated or sheared geotransform (terms %g, %g); warp it to a north-up grid first",
                              name, transform[2], transform[4]);
        goto done;
    }
    if (georeferenced && (!(transform[1] != 0.0) || !(transform[5] != 0.0) || !isfinite(transform[1]) ||
                          !isfinite(transform[5]) || !isfinite(transform[0]) || !isfinite(transform[3]))) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: invalid geotransform (pixel size %g x %g)", name, transform[1],
                              transform[5]);
        goto done;
    }
    if (!georeferenced) {
        /* Image convention: rows go down (southwards), unit pixels scaled by
         * options->spacing. */
        transform[0] = 0.0;
        transform[1] = options->spacing;
        transform[2] = 0.0;
        transform[3] = (double)height * options->spacing;
        transform[4] = 0.0;
        transform[5] = -options->spacing;
    }

    GDALRasterBandH band = gdal->GDALGetRasterBand(dataset, options->band);
    int has_nodata = 0;
    double nodata = gdal->GDALGetRasterNoDataValue(band, &has_nodata);
    int has_scale = 0, has_offset = 0;
    double scale = gdal->GDALGetRasterScale(band, &has_scale);
    double offset = gdal->GDALGetRasterOffset(band, &has_offset);
    if (!has_scale || !isfinite(scale)) scale = 1.0;
    if (!has_offset || !isfinite(offset)) offset = 0.0;
    double vertical = unit_factor(gdal->GDALGetRasterUnitType(band)) * options->z_scale;

    status = dem_charge(&budget, width * height, sizeof(float) + 1, name, width, height, error);
    if (status != LK_OK) goto done;
    float *raw = lk__malloc_array(width * height, sizeof *raw);
    valid = lk__malloc_array(width * height, 1);
    if (!raw || !valid) {
        free(raw);
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for a %zux%zu grid", name, width, height);
        goto done;
    }
    gdal->CPLErrorReset();
    GDALRasterIOExtraArg read_progress;
    INIT_RASTERIO_EXTRA_ARG(read_progress);
    read_progress.pfnProgress = gdal_progress;
    read_progress.pProgressData = (void *)options;
    if (gdal->GDALRasterIOEx(band, GF_Read, 0, 0, x_size, y_size, raw, x_size, y_size, GDT_Float32, 0, 0,
                             options->progress ? &read_progress : NULL) != CE_None) {
        free(raw);
        status = gdal_error(gdal, error, LK_ERR_IO, path, name, "reading the raster failed");
        goto done;
    }

    /* The no-data value compared as GDAL delivers it (converted to float). */
    float nodata_float = (float)nodata;
    bool nodata_usable = has_nodata && !isnan(nodata);
    bool flip_x = transform[1] < 0.0, flip_y = transform[5] < 0.0;
    out->width = width;
    out->height = height;
    out->heights = raw;
    /* Flip in place so that x grows eastwards and y northwards. */
    if (flip_y)
        for (size_t j = 0; j < height / 2; j++) {
            float *a = raw + j * width, *b = raw + (height - 1 - j) * width;
            for (size_t i = 0; i < width; i++) {
                float t = a[i];
                a[i] = b[i];
                b[i] = t;
            }
        }
    if (flip_x)
        for (size_t j = 0; j < height; j++) {
            float *row = raw + j * width;
            for (size_t i = 0; i < width / 2; i++) {
                float t = row[i];
                row[i] = row[width - 1 - i];
                row[width - 1 - i] = t;
            }
        }
    for (size_t k = 0; k < width * height; k++) {
        float value = raw[k];
        bool ok = isfinite(value) && !(nodata_usable && value == nodata_float);
        if (ok) {
            double h = ((double)value * scale + offset) * vertical;
            ok = isfinite(h) && fabs(h) <= (double)3.0e38f;
            raw[k] = ok ? (float)h : 0.0f;
        } else {
            raw[k] = 0.0f;
        }
        valid[k] = ok;
    }

    /* Centre of the south-west sample and the sample steps, in CRS units. */
    double step_x = fabs(transform[1]), step_y = fabs(transform[5]);
    double west = fmin(transform[0], transform[0] + transform[1] * (double)width);
    double south = fmin(transform[3], transform[3] + transform[5] * (double)height);
    double first_x = west + 0.5 * step_x, first_y = south + 0.5 * step_y;
    status = set_georeference(out, first_x, first_y, step_x, step_y,
                              georeferenced && is_geographic(gdal, dataset, transform, width, height), name, error);
    if (status != LK_OK) goto done;
    status = finish_field(out, valid, &budget, name, error);
    valid = NULL;

done:
    if (status != LK_OK) {
        free(valid);
        lk_heightfield_free(out);
    }
    if (dataset) gdal->GDALClose(dataset);
    gdal->CPLErrorReset();
    gdal->CPLPopErrorHandler();
    gdal_settings_restore(gdal, settings, sizeof settings / sizeof settings[0]);
    return status;
}

static bool has_extension(const char *path, const char *ext)
{
    const char *base = base_name(path);
    const char *dot = strrchr(base, '.');
    if (!dot) return false;
    size_t len = strlen(dot + 1);
    return len == strlen(ext) && lk__word_equals(dot + 1, len, ext);
}

/* ---- PGM (P2 ascii, P5 binary) ---------------------------------------- */

/* Header cursor: tracks the line for messages (the header is text even in
 * P5 files). */
typedef struct pgm_cursor {
    const unsigned char *data;
    size_t size, pos, line;
    const char *name;
} pgm_cursor;

static bool pgm_is_space(unsigned char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

/* Skips whitespace and '#' comments (to the end of their line). */
static void pgm_skip(pgm_cursor *c)
{
    while (c->pos < c->size) {
        unsigned char ch = c->data[c->pos];
        if (ch == '#') {
            while (c->pos < c->size && c->data[c->pos] != '\n') c->pos++;
        } else if (pgm_is_space(ch)) {
            if (ch == '\n') c->line++;
            c->pos++;
        } else {
            break;
        }
    }
}

static void pgm_quote(const pgm_cursor *c, char *out, size_t out_size)
{
    size_t length = 0;
    while (c->pos + length < c->size && length < 16 && length + 1 < out_size) {
        unsigned char ch = c->data[c->pos + length];
        if (pgm_is_space(ch)) break;
        out[length++] = (ch >= 32 && ch < 127) ? (char)ch : '?';
    }
    out[length] = '\0';
}

/* Reads an unsigned decimal number after whitespace/comments; `what` names
 * it in the message. Values above `limit` are refused. */
static lk_status pgm_number(pgm_cursor *c, const char *what, unsigned long long limit, unsigned long long *value,
                            lk_error *error)
{
    pgm_skip(c);
    if (c->pos >= c->size)
        return lk__error_at_line(error, LK_ERR_PARSE, c->name, c->line,
                                 "expected the %s, found the end of the file (byte %zu)", what, c->pos);
    if (c->data[c->pos] < '0' || c->data[c->pos] > '9') {
        char token[24];
        pgm_quote(c, token, sizeof token);
        return lk__error_at_line(error, LK_ERR_PARSE, c->name, c->line, "expected the %s, got '%s' (byte %zu)", what,
                                 token, c->pos);
    }
    unsigned long long v = 0;
    size_t start = c->pos;
    while (c->pos < c->size && c->data[c->pos] >= '0' && c->data[c->pos] <= '9') {
        v = v * 10 + (unsigned)(c->data[c->pos] - '0');
        c->pos++;
        if (v > limit)
            return lk__error_at_line(error, LK_ERR_PARSE, c->name, c->line, "%s too large (more than %llu, byte %zu)",
                                     what, limit, start);
    }
    if (c->pos < c->size && !pgm_is_space(c->data[c->pos]) && c->data[c->pos] != '#') {
        char token[24];
        c->pos = start;
        pgm_quote(c, token, sizeof token);
        return lk__error_at_line(error, LK_ERR_PARSE, c->name, c->line, "expected the %s, got '%s' (byte %zu)", what,
                                 token, start);
    }
    *value = v;
    return LK_OK;
}

/* Allocates an image-sized field (heights and validity flags) with the
 * options' spacing; readers store image row r in field row height-1-r
 * (the top of the image is north). */
static lk_status alloc_image_field(const char *name, size_t width, size_t height, const lk_dem_options *options,
                                   lk__budget *budget, lk_heightfield *out, unsigned char **valid, lk_error *error)
{
    lk_status status = dem_charge(budget, width * height, sizeof *out->heights + 1, name, width, height, error);
    if (status != LK_OK) return status;
    out->heights = lk__malloc_array(width * height, sizeof *out->heights);
    *valid = lk__malloc_array(width * height, 1);
    if (!out->heights || !*valid) {
        free(*valid);
        *valid = NULL;
        lk_heightfield_free(out);
        return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for a %zux%zu grid", name, width, height);
    }
    out->width = width;
    out->height = height;
    out->spacing_x = options->spacing;
    out->spacing_y = options->spacing;
    out->origin_x = 0.0;
    out->origin_y = 0.0;
    return LK_OK;
}

static lk_status read_pgm(const unsigned char *data, size_t size, const char *name, const lk_dem_options *options,
                          lk__budget *budget, lk_heightfield *out, lk_error *error)
{
    pgm_cursor c = {data, size, 0, 1, name};
    if (size < 2 || data[0] != 'P' || (data[1] != '2' && data[1] != '5')) {
        char token[24];
        pgm_quote(&c, token, sizeof token);
        if (size >= 2 && data[0] == 'P' && data[1] >= '1' && data[1] <= '7')
            return lk_error_set(error, LK_ERR_UNSUPPORTED,
                                "%s: byte 0: netpbm type P%c is not a greyscale PGM (only P2 and P5 hold heights)",
                                name, data[1]);
        return lk_error_set(error, LK_ERR_PARSE, "%s: byte 0: not a PGM file: magic '%s' (expected P2 or P5)", name,
                            token);
    }
    bool binary = data[1] == '5';
    c.pos = 2;
    if (c.pos < size && !pgm_is_space(data[c.pos]) && data[c.pos] != '#')
        return lk_error_set(error, LK_ERR_PARSE, "%s: byte 2: expected whitespace after the magic number", name);
    unsigned long long width, height, maxval;
    lk_status status = pgm_number(&c, "width", 0xFFFFFFFFull, &width, error);
    if (status == LK_OK) status = pgm_number(&c, "height", 0xFFFFFFFFull, &height, error);
    if (status == LK_OK) {
        status = pgm_number(&c, "maxval", 0xFFFFFFFFull, &maxval, error);
        if (status == LK_OK && (maxval < 1 || maxval > 65535))
            status = lk__error_at_line(error, LK_ERR_PARSE, name, c.line, "maxval %llu out of range 1..65535", maxval);
    }
    if (status != LK_OK) return status;
    status = check_size(name, (size_t)width, (size_t)height, options->max_samples, error);
    if (status != LK_OK) return status;
    size_t count = (size_t)width * (size_t)height;
    double scale = options->image_height_range * options->z_scale / (double)maxval;

    unsigned char *valid = NULL;
    if (binary) {
        /* Exactly one whitespace byte separates maxval from the raster. */
        if (c.pos >= size)
            return lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: file ends after the header (no samples)", name,
                                c.pos);
        if (!pgm_is_space(data[c.pos]))
            return lk_error_set(error, LK_ERR_PARSE,
                                "%s: byte %zu: expected one whitespace byte between maxval and the raster", name,
                                c.pos);
        size_t raster = c.pos + 1;
        size_t bytes_per_sample = maxval < 256 ? 1 : 2;
        size_t available = size - raster;
        if (available / bytes_per_sample < count)
            return lk_error_set(
                error, LK_ERR_PARSE,
                "%s: byte %zu: truncated raster: %zux%zu samples of %zu byte%s need %zu bytes from byte %zu, "
                "only %zu present",
                name, size, (size_t)width, (size_t)height, bytes_per_sample, bytes_per_sample == 1 ? "" : "s",
                count * bytes_per_sample, raster, available);
        status = alloc_image_field(name, (size_t)width, (size_t)height, options, budget, out, &valid, error);
        if (status != LK_OK) return status;
        for (size_t k = 0; k < count; k++) {
            size_t at = raster + k * bytes_per_sample;
            unsigned sample = bytes_per_sample == 1 ? data[at] : (unsigned)data[at] << 8 | data[at + 1];
            if (sample > maxval) {
                free(valid);
                lk_heightfield_free(out);
                return lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: sample %u exceeds maxval %llu", name, at,
                                    sample, maxval);
            }
            size_t i = k % (size_t)width, j = (size_t)height - 1 - k / (size_t)width;
            out->heights[j * (size_t)width + i] = (float)(sample * scale);
            valid[j * (size_t)width + i] = 1;
        }
    } else {
        /* Every sample takes at least one digit and one separator (but the
         * last): refuse claims the file cannot hold before allocating. */
        if ((size - c.pos) / 2 + 1 < count)
            return lk__error_at_line(error, LK_ERR_PARSE, name, c.line,
                                     "%zux%zu samples cannot fit in the %zu bytes after the header (file truncated?)",
                                     (size_t)width, (size_t)height, size - c.pos);
        status = alloc_image_field(name, (size_t)width, (size_t)height, options, budget, out, &valid, error);
        if (status != LK_OK) return status;
        for (size_t k = 0; k < count; k++) {
            unsigned long long sample;
            status = pgm_number(&c, "sample", 0xFFFFFFFFull, &sample, error);
            if (status == LK_OK && sample > maxval)
                status = lk__error_at_line(error, LK_ERR_PARSE, name, c.line, "sample %llu exceeds maxval %llu", sample,
                                           maxval);
            if (status != LK_OK) {
                free(valid);
                lk_heightfield_free(out);
                return status;
            }
            size_t i = k % (size_t)width, j = (size_t)height - 1 - k / (size_t)width;
            out->heights[j * (size_t)width + i] = (float)((double)sample * scale);
            valid[j * (size_t)width + i] = 1;
        }
    }
    return finish_field(out, valid, budget, name, error);
}

/* ---- PNG (libpng) ------------------------------------------------------- */

/* State shared with libpng's callbacks; everything that must survive a
 * longjmp lives here rather than in locals of the function that calls
 * setjmp. */
typedef struct png_job {
    const unsigned char *data;
    size_t size, pos;
    const char *name;
    char message[200];
    png_structp png;
    png_infop info;
    unsigned char *pixels;
    png_bytep *rows;
    size_t pixel_bytes; /* pixels and rows, charged to the budget */
    lk__budget *budget;
    bool bad_data; /* a warning said the image data is incomplete */
} png_job;

static void png_read_callback(png_structp png, png_bytep target, size_t length)
{
    png_job *job = png_get_io_ptr(png);
    if (length > job->size - job->pos) {
        job->pos = job->size;
        png_error(png, "file truncated");
    }
    memcpy(target, job->data + job->pos, length);
    job->pos += length;
}

static void png_error_callback(png_structp png, png_const_charp message)
{
    png_job *job = png_get_error_ptr(png);
    snprintf(job->message, sizeof job->message, "%s", message);
    png_longjmp(png, 1);
}

/* Warnings about ancillary chunks (colour profiles, text, ...) and extra
 * compressed data after the last row do not matter for heights, but libpng
 * only warns when the image data ends before the last row ("Not enough
 * image data"): the missing rows would be made up, so that is an error. */
static void png_warning_callback(png_structp png, png_const_charp message)
{
    png_job *job = png_get_error_ptr(png);
    if (!job->bad_data && strstr(message, "Not enough image data")) {
        job->bad_data = true;
        snprintf(job->message, sizeof job->message, "%s", message);
    }
}

/* Decodes the whole image into job->pixels as 8 or 16-bit grey, grey+alpha,
 * RGB or RGBA samples; returns false after a libpng error (message in job). */
static bool png_decode(png_job *job, const lk_dem_options *options, size_t *width, size_t *height, int *channels,
                       int *depth, lk_status *size_status, lk_error *error)
{
    if (setjmp(png_jmpbuf(job->png))) return false;
    png_set_read_fn(job->png, job, png_read_callback);
    png_read_info(job->png, job->info);
    png_uint_32 w = png_get_image_width(job->png, job->info), h = png_get_image_height(job->png, job->info);
    *size_status = check_size(job->name, w, h, options->max_samples, error);
    if (*size_status != LK_OK) return false;
    int colour = png_get_color_type(job->png, job->info);
    int bits = png_get_bit_depth(job->png, job->info);
    if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(job->png);
    if (colour == PNG_COLOR_TYPE_GRAY && bits < 8) png_set_expand_gray_1_2_4_to_8(job->png);
    if (png_get_valid(job->png, job->info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(job->png);
    png_set_interlace_handling(job->png);
    png_read_update_info(job->png, job->info);
    *channels = png_get_channels(job->png, job->info);
    *depth = png_get_bit_depth(job->png, job->info);
    size_t row_bytes = png_get_rowbytes(job->png, job->info);
    if (*depth != 8 && *depth != 16) png_error(job->png, "unexpected bit depth after expansion");
    if (row_bytes < (size_t)w * (size_t)*channels * (size_t)(*depth / 8))
        png_error(job->png, "row size smaller than expected");
    if (h == 0 || row_bytes > (SIZE_MAX - h * sizeof *job->rows) / h) png_error(job->png, "bad image size");
    *size_status = dem_charge(job->budget, h, row_bytes + sizeof *job->rows, job->name, w, h, error);
    if (*size_status != LK_OK) return false;
    job->pixel_bytes = h * (row_bytes + sizeof *job->rows);
    /* Zeroed so that nothing depends on uninitialised memory even if
     * libpng leaves rows unwritten. */
    job->pixels = lk__calloc_array(row_bytes, h);
    job->rows = lk__malloc_array(h, sizeof *job->rows);
    if (!job->pixels || !job->rows) {
        *size_status =
            lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for a %ux%u PNG", job->name, (unsigned)w, (unsigned)h);
        return false;
    }
    for (png_uint_32 j = 0; j < h; j++) job->rows[j] = job->pixels + (size_t)j * row_bytes;
    png_read_image(job->png, job->rows);
    if (job->bad_data) return false;
    /* The end chunk is not needed: stop here so that trailing damage after
     * the image data does not refuse a readable heightmap. */
    *width = w;
    *height = h;
    return true;
}

static lk_status read_png(const unsigned char *data, size_t size, const char *name, const lk_dem_options *options,
                          lk__budget *budget, lk_heightfield *out, lk_error *error)
{
    png_job job;
    memset(&job, 0, sizeof job);
    job.budget = budget;
    job.data = data;
    job.size = size;
    job.name = name;
    job.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &job, png_error_callback, png_warning_callback);
    if (!job.png) return lk_error_set(error, LK_ERR_NOMEM, "%s: libpng could not start", name);
    job.info = png_create_info_struct(job.png);
    if (!job.info) {
        png_destroy_read_struct(&job.png, NULL, NULL);
        return lk_error_set(error, LK_ERR_NOMEM, "%s: libpng could not start", name);
    }
    size_t width = 0, height = 0;
    int channels = 0, depth = 0;
    lk_status status = LK_OK;
    unsigned char *valid = NULL;
    if (!png_decode(&job, options, &width, &height, &channels, &depth, &status, error)) {
        if (status == LK_OK)
            status = lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: PNG: %s", name, job.pos,
                                  job.message[0] ? job.message : "decoding failed");
        goto done;
    }
    /* Grey PNGs give the heights directly. Colour PNGs (RGB, palette) are
     * accepted only when every pixel is grey (r == g == b), as image
     * editors often save greyscale heightmaps that way; real colour (e.g.
     * height packed into RGB) is refused rather than guessed at. Alpha 0
     * (or a tRNS-transparent value) marks no-data. */
    bool colour = channels >= 3;
    bool alpha = channels == 2 || channels == 4;
    size_t bytes = (size_t)depth / 8;
    double maxval = depth == 16 ? 65535.0 : 255.0;
    double scale = options->image_height_range * options->z_scale / maxval;
    status = alloc_image_field(name, width, height, options, budget, out, &valid, error);
    if (status != LK_OK) goto done;
    for (size_t row = 0; row < height; row++) {
        const unsigned char *pixel = job.rows[row];
        size_t j = height - 1 - row;
        for (size_t i = 0; i < width; i++, pixel += (size_t)channels * bytes) {
            unsigned sample[4];
            for (int ch = 0; ch < channels; ch++)
                sample[ch] = bytes == 1 ? pixel[ch] : (unsigned)pixel[2 * ch] << 8 | pixel[2 * ch + 1];
            if (colour && (sample[0] != sample[1] || sample[1] != sample[2])) {
                status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                                      "%s: colour PNG: pixel (%zu, %zu) is (%u, %u, %u), not grey; heightmaps must be "
                                      "greyscale (colour PNGs are read only when every pixel has r = g = b)",
                                      name, i, row, sample[0], sample[1], sample[2]);
                free(valid);
                valid = NULL;
                lk_heightfield_free(out);
                goto done;
            }
            bool transparent = alpha && sample[channels - 1] == 0;
            out->heights[j * width + i] = transparent ? 0.0f : (float)((double)sample[0] * scale);
            valid[j * width + i] = !transparent;
        }
    }
    /* The decoded rows go before the no-data fill needs its room. */
    free(job.pixels);
    free(job.rows);
    job.pixels = NULL;
    job.rows = NULL;
    lk__budget_release(budget, job.pixel_bytes, 1);
    job.pixel_bytes = 0;
    status = finish_field(out, valid, budget, name, error);
    valid = NULL;
done:
    png_destroy_read_struct(&job.png, &job.info, NULL);
    free(job.pixels);
    free(job.rows);
    lk__budget_release(budget, job.pixel_bytes, 1);
    free(valid);
    return status;
}

/* ---- NumPy .npz archives ------------------------------------------------ */

/* matplotlib ships real DEMs as NumPy archives (jacksboro_fault_dem.npz): a
 * zip of .npy arrays, a 2-D "elevation" plus scalars dx, dy (sample spacing)
 * and xmin, ymin/ymax. Only what such archives use is read: stored or
 * deflated members (no zip64, no encryption), little-endian or byte-sized
 * integers and floats in C order. */

typedef struct npz_member {
    char name[64];
    unsigned char *data;
    size_t size;
} npz_member;

static void npz_free(npz_member *members, size_t count, lk__budget *budget)
{
    for (size_t i = 0; i < count; i++) {
        free(members[i].data);
        if (members[i].data) lk__budget_release(budget, members[i].size, 1);
    }
    free(members);
}

/* Inflates every member listed in the central directory. Each member's size
 * is checked against the archive (deflate expands at most ~1032:1) and
 * against max_bytes before anything is allocated; the members are charged
 * to the budget. */
static lk_status npz_members(const unsigned char *zip, size_t size, const char *name, size_t max_bytes,
                             lk__budget *budget, npz_member **out, size_t *count, lk_error *error)
{
    *out = NULL;
    *count = 0;
    if (size < 22) return lk_error_set(error, LK_ERR_PARSE, "%s: not a zip archive (%zu bytes)", name, size);
    size_t eocd = size - 22;
    size_t stop = size > 22 + 65535 ? size - 22 - 65535 : 0;
    while (lk__load_u32le(zip + eocd) != 0x06054b50u) {
        if (eocd == stop)
            return lk_error_set(error, LK_ERR_PARSE, "%s: not a zip archive (no end-of-directory record)", name);
        eocd--;
    }
    size_t entries = lk__load_u16le(zip + eocd + 10);
    size_t offset = lk__load_u32le(zip + eocd + 16);
    if (entries > size / 46)
        return lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: %zu directory entries cannot fit in %zu bytes", name,
                            eocd, entries, size);
    npz_member *members = lk__calloc_array(entries ? entries : 1, sizeof *members);
    if (!members) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
    /* On failure every member up to n is freed: calloc left the others NULL. */
    lk_status status = LK_OK;
    size_t total = 0, n = 0;
    for (; n < entries; n++) {
        if (offset > size || size - offset < 46 || lk__load_u32le(zip + offset) != 0x02014b50u) {
            status = lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: expected a zip directory entry", name, offset);
            goto fail;
        }
        const unsigned char *entry = zip + offset;
        uint32_t method = lk__load_u16le(entry + 10), packed = lk__load_u32le(entry + 20),
                 unpacked = lk__load_u32le(entry + 24);
        size_t name_length = lk__load_u16le(entry + 28), extra = lk__load_u16le(entry + 30),
               comment = lk__load_u16le(entry + 32);
        size_t local = lk__load_u32le(entry + 42);
        if (size - offset - 46 < name_length) {
            status = lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: member name runs past the end", name, offset);
            goto fail;
        }
        snprintf(members[n].name, sizeof members[n].name, "%.*s", (int)(name_length < 63 ? name_length : 63),
                 (const char *)entry + 46);
        offset += 46 + name_length + extra + comment;
        if (local > size || size - local < 30 || lk__load_u32le(zip + local) != 0x04034b50u) {
            status = lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: expected a zip local header for %s", name, local,
                                  members[n].name);
            goto fail;
        }
        size_t data_offset = local + 30 + lk__load_u16le(zip + local + 26) + lk__load_u16le(zip + local + 28);
        if (data_offset > size || size - data_offset < packed) {
            status = lk_error_set(error, LK_ERR_TRUNCATED, "%s: byte %zu: member %s (%u bytes) runs past the end", name,
                                  data_offset, members[n].name, (unsigned)packed);
            goto fail;
        }
        if ((method == 0 && packed != unpacked) || (method == 8 && unpacked / 1032 > (size_t)packed + 1)) {
            status = lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: member %s claims %u bytes from %u", name, local,
                                  members[n].name, (unsigned)unpacked, (unsigned)packed);
            goto fail;
        }
        total += unpacked;
        if (total > max_bytes) {
            status = lk_error_set(error, LK_ERR_LIMIT, "%s: archive inflates to more than %zu bytes", name, max_bytes);
            goto fail;
        }
        if (method != 0 && method != 8) {
            status =
                lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: member %s uses zip method %u (only stored and deflated)",
                             name, members[n].name, (unsigned)method);
            goto fail;
        }
        if (!lk__budget_charge(budget, unpacked, 1)) {
            status = lk_error_set(error, LK_ERR_LIMIT,
                                  "%s: member %s (%u bytes) needs more than %zu bytes with the rest (max_samples x %u "
                                  "bytes per sample)",
                                  name, members[n].name, (unsigned)unpacked, budget->limit, LK_DEM_BYTES_PER_SAMPLE);
            goto fail;
        }
        members[n].data = malloc(unpacked ? unpacked : 1);
        members[n].size = unpacked;
        if (!members[n].data) {
            lk__budget_release(budget, unpacked, 1);
            status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for member %s", name, members[n].name);
            goto fail;
        }
        if (method == 0) {
            memcpy(members[n].data, zip + data_offset, unpacked);
            continue;
        }
        z_stream z;
        memset(&z, 0, sizeof z);
        if (inflateInit2(&z, -15) != Z_OK) {
            status = lk_error_set(error, LK_ERR_NOMEM, "%s: cannot start inflating %s", name, members[n].name);
            goto fail;
        }
        z.next_in = (Bytef *)(uintptr_t)(zip + data_offset);
        z.avail_in = packed;
        z.next_out = members[n].data;
        z.avail_out = unpacked;
        int result = inflate(&z, Z_FINISH);
        size_t produced = z.total_out;
        inflateEnd(&z);
        if (result != Z_STREAM_END || produced != unpacked) {
            status = lk_error_set(error, LK_ERR_PARSE, "%s: byte %zu: member %s does not inflate to its %u bytes", name,
                                  data_offset, members[n].name, (unsigned)unpacked);
            goto fail;
        }
    }
    *out = members;
    *count = entries;
    return LK_OK;
fail:
    npz_free(members, n < entries ? n + 1 : entries, budget);
    return status;
}

/* A parsed .npy array: little-endian (or byte-sized) numbers, C order. */
typedef struct npy_array {
    char kind;     /* 'i', 'u', 'f' */
    unsigned item; /* bytes per item */
    size_t dims[2];
    unsigned dim_count;
    const unsigned char *data;
    size_t count;
} npy_array;

/* 0 when the member is not an array this reader understands (it is then
 * ignored, like the archive's other members). */
static int npy_parse(const npz_member *member, npy_array *out)
{
    const unsigned char *d = member->data;
    if (member->size < 12 || memcmp(d, "\x93NUMPY", 6) != 0) return 0;
    size_t header_length = d[6] == 1 ? lk__load_u16le(d + 8) : lk__load_u32le(d + 8);
    size_t start = d[6] == 1 ? 10 : 12;
    if (member->size - start < header_length) return 0;
    char header[512];
    snprintf(header, sizeof header, "%.*s", (int)(header_length < 511 ? header_length : 511), (const char *)d + start);
    const char *descr = strstr(header, "'descr':");
    const char *fortran = strstr(header, "'fortran_order':");
    const char *shape = strstr(header, "'shape':");
    if (!descr || !shape || (fortran && strstr(fortran, "True"))) return 0;
    descr = strchr(descr + 8, '\'');
    if (!descr || (descr[1] != '<' && descr[1] != '|')) return 0;
    out->kind = descr[2];
    out->item = (unsigned)atoi(descr + 3);
    if ((out->kind != 'i' && out->kind != 'u' && out->kind != 'f') ||
        (out->item != 1 && out->item != 2 && out->item != 4 && out->item != 8) || (out->kind == 'f' && out->item < 4))
        return 0;
    const char *p = strchr(shape, '(');
    if (!p) return 0;
    p++;
    out->dim_count = 0;
    out->count = 1;
    while (*p && *p != ')') {
        while (*p == ' ' || *p == ',') p++;
        if (*p == ')') break;
        char *end;
        unsigned long long value = strtoull(p, &end, 10);
        if (end == p || out->dim_count == 2 || value > (1u << 24)) return 0;
        out->dims[out->dim_count++] = (size_t)value;
        if (value && out->count > SIZE_MAX / value) return 0;
        out->count *= (size_t)value;
        p = end;
    }
    out->data = d + start + header_length;
    return (member->size - start - header_length) / out->item >= out->count;
}

static double npy_value(const npy_array *array, size_t index)
{
    return lk__load_number_le(array->data + index * array->item, array->item, array->kind);
}

/* The 2-D array named "elevation" (else the first 2-D one) is the grid, its
 * first row north; dx/dy are the spacing (one given = both), xmin and
 * ymin/ymax the position. Spacings under one unit with coordinates inside
 * [-180, 180] x [-90, 90] are degrees and get metres like GDAL grids. */
static lk_status read_npz(const unsigned char *data, size_t size, const char *name, const lk_dem_options *options,
                          lk__budget *budget, lk_heightfield *out, lk_error *error)
{
    npz_member *members = NULL;
    size_t count = 0;
    size_t max_bytes = options->max_samples > SIZE_MAX / 16 ? SIZE_MAX : options->max_samples * 16;
    lk_status status = npz_members(data, size, name, max_bytes, budget, &members, &count, error);
    if (status != LK_OK) return status;
    npy_array grid = {0};
    int found = 0, have_dx = 0, have_dy = 0, have_ymax = 0;
    double dx = 1, dy = 1, xmin = 0, ymin = 0, ymax = 0;
    for (size_t i = 0; i < count; i++) {
        npy_array array;
        if (!npy_parse(&members[i], &array)) continue;
        if (array.dim_count == 2 && (!found || strcmp(members[i].name, "elevation.npy") == 0)) {
            grid = array;
            found = 1;
        } else if (array.dim_count == 0 && array.count == 1) {
            double value = npy_value(&array, 0);
            if (strcmp(members[i].name, "dx.npy") == 0)
                dx = value, have_dx = 1;
            else if (strcmp(members[i].name, "dy.npy") == 0)
                dy = value, have_dy = 1;
            else if (strcmp(members[i].name, "xmin.npy") == 0)
                xmin = value;
            else if (strcmp(members[i].name, "ymin.npy") == 0)
                ymin = value;
            else if (strcmp(members[i].name, "ymax.npy") == 0)
                ymax = value, have_ymax = 1;
        }
    }
    unsigned char *valid = NULL;
    if (!found) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no 2-D numeric array in the archive", name);
        goto done;
    }
    size_t rows = grid.dims[0], columns = grid.dims[1];
    status = check_size(name, columns, rows, options->max_samples, error);
    if (status != LK_OK) goto done;
    if (have_dx && !have_dy) dy = dx;
    if (have_dy && !have_dx) dx = dy;
    if (!(dx > 0) || !(dy > 0) || !isfinite(dx) || !isfinite(dy) || !isfinite(xmin) || !isfinite(ymin) ||
        !isfinite(ymax)) {
        status = lk_error_set(error, LK_ERR_RANGE, "%s: bad georeference (dx %g, dy %g, xmin %g, ymin %g)", name, dx,
                              dy, xmin, ymin);
        goto done;
    }
    status = alloc_image_field(name, columns, rows, options, budget, out, &valid, error);
    if (status != LK_OK) goto done;
    for (size_t j = 0; j < rows; j++)
        for (size_t i = 0; i < columns; i++) {
            double value = npy_value(&grid, (rows - 1 - j) * columns + i) * options->z_scale;
            size_t k = j * columns + i;
            valid[k] = isfinite(value) && fabs(value) < 1e30;
            out->heights[k] = valid[k] ? (float)value : 0.0f;
        }
    /* xmin/ymin/ymax are the grid's outer edges (in matplotlib's file
     * xmax - xmin = columns * dx, and "ymin" is the northern edge), so the
     * sample centres, which the heightfield's origin names, are half a
     * cell inside. */
    double south = (have_ymax && ymax < ymin ? ymax : ymin) + 0.5 * dy;
    double west = xmin + 0.5 * dx;
    status = set_georeference(out, west, south, dx, dy, dx < 1 && dy < 1 && fabs(xmin) <= 180 && fabs(south) <= 90,
                              name, error);
    if (status != LK_OK) goto done;
    status = finish_field(out, valid, budget, name, error);
    valid = NULL;
done:
    free(valid);
    if (status != LK_OK) lk_heightfield_free(out);
    npz_free(members, count, budget);
    return status;
}

/* In-memory entry point for our own formats (tests and the fuzz target
 * declare it themselves; it is not part of the public API). Dispatches by
 * magic bytes, then by the extension of `name`. */
lk_status lk__dem_read_memory(const void *data, size_t size, const char *name, const lk_dem_options *options,
                              lk_heightfield *out, lk_error *error);

static lk_status file_too_large(const char *name, unsigned long long size, const lk_dem_options *options,
                                const lk__budget *budget, lk_error *error)
{
    return lk_error_set(error, LK_ERR_LIMIT,
                        "%s: the file has %llu bytes, more than %llu (max_samples %zu x %u bytes per sample)", name,
                        size, (unsigned long long)budget->limit, options->max_samples, LK_DEM_BYTES_PER_SAMPLE);
}

/* `budget` holds the input's bytes already. */
static lk_status read_own_format(const unsigned char *bytes, size_t size, const char *name,
                                 const lk_dem_options *options, lk__budget *budget, lk_heightfield *out,
                                 lk_error *error)
{
    if (size >= 8 && memcmp(bytes, "\x89PNG\r\n\x1a\n", 8) == 0)
        return read_png(bytes, size, name, options, budget, out, error);
    if ((size >= 2 && bytes[0] == 'P' && bytes[1] >= '1' && bytes[1] <= '7') || has_extension(name, "pgm"))
        return read_pgm(bytes, size, name, options, budget, out, error);
    if (has_extension(name, "png")) return read_png(bytes, size, name, options, budget, out, error);
    if ((size >= 4 && memcmp(bytes, "PK\x03\x04", 4) == 0) || has_extension(name, "npz"))
        return read_npz(bytes, size, name, options, budget, out, error);
    return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: not a PGM (P2/P5) or PNG heightmap or a NumPy .npz archive",
                        name);
}

lk_status lk__dem_read_memory(const void *data, size_t size, const char *name, const lk_dem_options *options,
                              lk_heightfield *out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "dem: out is NULL");
    memset(out, 0, sizeof *out);
    if (!data && size) return lk_error_set(error, LK_ERR_INVALID, "dem: data is NULL");
    if (!name) name = "(memory)";
    lk_dem_options defaults;
    if (!options) {
        lk_dem_options_default(&defaults);
        options = &defaults;
    }
    lk_status status = check_options(options, error);
    if (status != LK_OK) return status;
    /* The caller's bytes are held while they are parsed, as a file's are. */
    lk__budget budget = dem_budget(options);
    if (!lk__budget_charge(&budget, size, 1)) return file_too_large(name, size, options, &budget, error);
    return read_own_format(data, size, name, options, &budget, out, error);
}

/* ---- entry points ------------------------------------------------------- */

/* A grid from an opened file: `path` for GDAL (which opens it again, and
 * must find the same file), `name` for messages. */
static lk_status read_opened_grid(int fd, const struct stat *info, const char *path, const char *name,
                                  const lk_dem_options *options, lk_heightfield *out, lk_error *error)
{
    /* Our own formats: by magic bytes first, then by extension (so that a
     * broken .pgm gets our parser's message rather than GDAL's). */
    unsigned char magic[8] = {0};
    ssize_t magic_size = pread(fd, magic, sizeof magic, 0);
    bool pgm = magic_size >= 2 && magic[0] == 'P' && (magic[1] == '2' || magic[1] == '5');
    bool png = magic_size >= 8 && memcmp(magic, "\x89PNG\r\n\x1a\n", 8) == 0;
    bool npz = magic_size >= 4 && memcmp(magic, "PK\x03\x04", 4) == 0 && has_extension(path, "npz");
    if (!(pgm || png || npz || has_extension(path, "pgm") || has_extension(path, "png") || has_extension(path, "npz")))
        return read_gdal(path, name, path, info, options, out, error);
    /* Our own formats are read whole, and the file counts against the
     * budget: one larger than it is refused before it is read. */
    lk__budget budget = dem_budget(options);
    if ((uint64_t)info->st_size > budget.limit)
        return file_too_large(name, (unsigned long long)info->st_size, options, &budget, error);
    char *data = NULL;
    size_t size = 0;
    lk_status status = lk__read_opened(fd, info, name, 0, &data, &size, error);
    if (status != LK_OK) return status;
    if (dem_progress(options, 0.4, "decoding"))
        status = lk_error_set(error, LK_ERR_INVALID, "%s: cancelled", name);
    else if (!lk__budget_charge(&budget, size, 1))
        status = file_too_large(name, size, options, &budget, error);
    else
        status = read_own_format((const unsigned char *)data, size, name, options, &budget, out, error);
    free(data);
    return status;
}

static lk_status prepare(const lk_dem_options **options, lk_dem_options *defaults, lk_heightfield *out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_dem_read: out is NULL");
    memset(out, 0, sizeof *out);
    if (!*options) {
        lk_dem_options_default(defaults);
        *options = defaults;
    }
    return check_options(*options, error);
}

lk_status lk__dem_read_opened(int fd, const struct stat *info, const char *path, const char *name,
                              const lk_dem_options *options, lk_heightfield *out, lk_error *error)
{
    lk_dem_options defaults;
    lk_status status = prepare(&options, &defaults, out, error);
    if (status != LK_OK) return status;
    return read_opened_grid(fd, info, path, name, options, out, error);
}

static lk_status dem_read(const char *path, const lk_dem_options *options, lk_heightfield *out, lk_error *error);

lk_status lk_dem_read(const char *path, const lk_dem_options *options, lk_heightfield *out, lk_error *error)
{
    lk_dem_options defaults;
    lk_status status = prepare(&options, &defaults, out, error);
    if (status != LK_OK) return status;
    if (dem_progress(options, 0.0, "reading"))
        return lk_error_set(error, LK_ERR_INVALID, "%s: cancelled", path ? path : "lk_dem_read");
    status = dem_read(path, options, out, error);
    if (status == LK_OK) (void)dem_progress(options, 1.0, "reading"); /* done: too late to cancel */
    return status;
}

static lk_status dem_read(const char *path, const lk_dem_options *options, lk_heightfield *out, lk_error *error)
{
    lk_status status;
    if (!path) return lk_error_set(error, LK_ERR_INVALID, "lk_dem_read: path is NULL");
    /* GDAL's virtual file systems reach archives, URLs and cloud storage,
     * which lk__open_input cannot check. */
    if (strncmp(path, "/vsi", 4) == 0)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: GDAL virtual file systems (/vsi...) are not read; extract or download the file first",
                            path);
    int fd;
    struct stat info;
    status = lk__open_input(NULL, path, &fd, &info, error);
    if (status == LK_OK) {
        status = read_opened_grid(fd, &info, path, base_name(path), options, out, error);
        close(fd);
        return status;
    }
    /* GDAL's subdataset syntax, DRIVER:"FILE":NAME (e.g. NETCDF:"f.nc":var):
     * FILE is checked like any input. */
    const char *colon = strchr(path, ':');
    const char *close_quote = colon && colon[1] == '"' ? strchr(colon + 2, '"') : NULL;
    if (errno != ENOENT || !close_quote || close_quote[1] != ':') return status;
    size_t length = (size_t)(close_quote - colon - 2);
    char *file = malloc(length + 1);
    if (!file) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    memcpy(file, colon + 2, length);
    file[length] = '\0';
    status = lk__open_input(NULL, file, &fd, &info, error);
    if (status == LK_OK) {
        status = read_gdal(path, path, file, &info, options, out, error);
        close(fd);
    }
    free(file);
    return status;
}
