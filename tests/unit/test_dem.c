/* SPDX-License-Identifier: MIT */
/* Elevation grids (src/io_dem.c): GDAL rasters (etopo20.cdf, GeoTIFFs made
 * here), our PGM and PNG heightmap readers, no-data filling, resampling. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gdal.h>
#include <ogr_srs_api.h>

#include "internal.h"
#include "testutil.h"

/* In-memory reader of src/io_dem.c (PGM and PNG only; not public). */
lk_status lk__dem_read_memory(const void *data, size_t size, const char *name, const lk_dem_options *options,
                              lk_heightfield *out, lk_error *error);

#define ETOPO_MIN (-9026.625)
#define ETOPO_MAX 6228.8125

/* Metres per degree on WGS84 at a latitude, written independently of the
 * library's formula (meridian and prime-vertical radii of curvature). */
static void wgs84_metres_per_degree(double latitude, double *per_lon, double *per_lat)
{
    double a = 6378137.0, inverse_flattening = 298.257223563;
    double flattening = 1.0 / inverse_flattening, e2 = 2.0 * flattening - flattening * flattening;
    double phi = latitude * 3.14159265358979323846 / 180.0;
    double denominator = 1.0 - e2 * sin(phi) * sin(phi);
    double radian = 3.14159265358979323846 / 180.0;
    *per_lon = radian * a * cos(phi) / sqrt(denominator);
    *per_lat = radian * a * (1.0 - e2) / pow(denominator, 1.5);
}

static void load_dem(const char *path, const lk_dem_options *options, lk_heightfield *field)
{
    lk_error error = {0};
    if (lk_dem_read(path, options, field, &error) != LK_OK) fail_msg("%s: %s", path, error.message);
}

static void expect_dem_failure(const char *path, const lk_dem_options *options, lk_status status, const char *needle)
{
    lk_heightfield field;
    lk_error error = {0};
    lk_status got = lk_dem_read(path, options, &field, &error);
    if (got != status)
        fail_msg("%s: expected %s, got %s (\"%s\")", path, lk_status_string(status), lk_status_string(got),
                 error.message);
    lk_assert_message_contains(error, needle);
    assert_null(field.heights);
    assert_int_equal(field.width, 0);
}

/* Reads from an exact-size heap copy so ASan catches reads past the end. */
static lk_status read_bytes(const void *bytes, size_t size, const char *name, const lk_dem_options *options,
                            lk_heightfield *field, lk_error *error)
{
    void *copy = malloc(size ? size : 1);
    assert_non_null(copy);
    memcpy(copy, bytes, size);
    lk_error_clear(error);
    lk_status status = lk__dem_read_memory(copy, size, name, options, field, error);
    free(copy);
    return status;
}

static void expect_bytes_failure(const void *bytes, size_t size, const char *name, lk_status status, const char *needle)
{
    lk_heightfield field;
    lk_error error;
    lk_status got = read_bytes(bytes, size, name, NULL, &field, &error);
    if (got != status)
        fail_msg("%s: expected %s, got %s (\"%s\")", name, lk_status_string(status), lk_status_string(got),
                 error.message);
    lk_assert_message_contains(error, needle);
    assert_null(field.heights);
}

static void write_file(const char *path, const void *bytes, size_t size)
{
    FILE *file = fopen(path, "wb");
    if (!file) fail_msg("cannot write %s", path);
    assert_int_equal(fwrite(bytes, 1, size, file), size);
    assert_int_equal(fclose(file), 0);
}

static void assert_all_finite(const lk_heightfield *field)
{
    for (size_t k = 0; k < field->width * field->height; k++)
        if (!isfinite(field->heights[k])) fail_msg("sample %zu is %g", k, (double)field->heights[k]);
}

static double row_mean(const lk_heightfield *field, size_t row)
{
    double sum = 0.0;
    for (size_t i = 0; i < field->width; i++) sum += field->heights[row * field->width + i];
    return sum / (double)field->width;
}

/* ---- etopo20.cdf (netCDF through GDAL, geographic, no CRS) -------------- */

static void test_etopo20(void **state)
{
    (void)state;
    lk_heightfield field;
    load_dem(lk_test_sample("etopo20.cdf"), NULL, &field);
    assert_int_equal(field.width, 1081);
    assert_int_equal(field.height, 540);
    assert_int_equal(field.nodata_count, 0);
    assert_all_finite(&field);
    /* 20' cells centred on latitudes -89.83..89.83: mean latitude 0, so the
     * spacing is a third of a degree on the equator. */
    double per_lon, per_lat;
    wgs84_metres_per_degree(0.0, &per_lon, &per_lat);
    assert_float_equal(field.spacing_x, per_lon / 3.0, 1e-6);
    assert_float_equal(field.spacing_y, per_lat / 3.0, 1e-6);
    assert_float_equal(field.spacing_x, 37106.5, 0.5);
    assert_float_equal(field.spacing_y, 36858.1, 0.5);
    /* First column centred on 20 1/6 deg east, first (southern) row on
     * -89 5/6 deg. */
    assert_float_equal(field.origin_x, (20.0 + 1.0 / 6.0) * per_lon, 1e-3);
    assert_float_equal(field.origin_y, -(90.0 - 1.0 / 6.0) * per_lat, 1e-3);
    /* The trench and the Himalaya at 20' resolution (GDAL's own min/max of
     * the band gives the same numbers). */
    assert_float_equal(field.min_height, ETOPO_MIN, 1e-3);
    assert_float_equal(field.max_height, ETOPO_MAX, 1e-3);
    assert_true(field.min_height < -8000.0);
    assert_true(field.max_height > 5000.0);
    /* y grows northwards: row 0 is the Antarctic plateau, the last row the
     * Arctic Ocean. */
    assert_true(row_mean(&field, 0) > 2000.0);
    assert_true(row_mean(&field, field.height - 1) < -1000.0);
    lk_heightfield_free(&field);
    assert_null(field.heights);

    /* GDAL's subdataset syntax reaches the same variable. */
    char name[4200];
    snprintf(name, sizeof name, "NETCDF:\"%s\":ROSE", lk_test_sample("etopo20.cdf"));
    load_dem(name, NULL, &field);
    assert_int_equal(field.width, 1081);
    assert_int_equal(field.height, 540);
    assert_float_equal(field.max_height, ETOPO_MAX, 1e-3);
    lk_heightfield_free(&field);
    snprintf(name, sizeof name, "NETCDF:\"%s\":NOSUCHVAR", lk_test_sample("etopo20.cdf"));
    expect_dem_failure(name, NULL, LK_ERR_UNSUPPORTED, "not a raster format GDAL can read");
}

static void test_etopo20_resample(void **state)
{
    (void)state;
    lk_heightfield field, resampled;
    lk_error error = {0};
    load_dem(lk_test_sample("etopo20.cdf"), NULL, &field);
    assert_int_equal(lk_heightfield_resample(&field, 1025, &resampled, &error), LK_OK);
    assert_int_equal(resampled.width, 1025);
    assert_int_equal(resampled.height, 1025);
    assert_int_equal(resampled.nodata_count, 0);
    assert_all_finite(&resampled);
    assert_true(resampled.min_height >= field.min_height);
    assert_true(resampled.max_height <= field.max_height);
    assert_true(resampled.min_height < -8000.0);
    assert_true(resampled.max_height > 5000.0);
    /* Same extent. */
    assert_float_equal(resampled.spacing_x * 1024.0, field.spacing_x * 1080.0, 1e-6);
    assert_float_equal(resampled.spacing_y * 1024.0, field.spacing_y * 539.0, 1e-6);
    assert_float_equal(resampled.origin_x, field.origin_x, 0.0);
    assert_float_equal(resampled.origin_y, field.origin_y, 0.0);
    /* Corners are copied. */
    assert_float_equal(resampled.heights[0], field.heights[0], 0.0);
    assert_float_equal(resampled.heights[1025 * 1025 - 1], field.heights[1081 * 540 - 1], 0.0);
    assert_float_equal(resampled.heights[1024], field.heights[1080], 0.0);
    lk_heightfield_free(&resampled);

    /* Size 0: the smallest 2^n + 1 covering 1081. */
    assert_int_equal(lk_heightfield_resample(&field, 0, &resampled, &error), LK_OK);
    assert_int_equal(resampled.width, 2049);
    assert_int_equal(resampled.height, 2049);
    lk_heightfield_free(&resampled);

    /* The budget is checked before reading. */
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.max_samples = 500000;
    expect_dem_failure(lk_test_sample("etopo20.cdf"), &options, LK_ERR_LIMIT, "1081x540");
    expect_dem_failure(lk_test_sample("etopo20.cdf"), &options, LK_ERR_LIMIT, "500000");
    lk_heightfield_free(&field);
}

/* ---- resampling ---------------------------------------------------------- */

static void make_plane(lk_heightfield *field, size_t width, size_t height)
{
    memset(field, 0, sizeof *field);
    field->width = width;
    field->height = height;
    field->heights = malloc(width * height * sizeof(float));
    assert_non_null(field->heights);
    field->spacing_x = 30.0;
    field->spacing_y = 12.5;
    field->origin_x = 1000.0;
    field->origin_y = -250.0;
    for (size_t j = 0; j < height; j++)
        for (size_t i = 0; i < width; i++)
            field->heights[j * width + i] = (float)(0.5 * (double)i - 0.25 * (double)j + 100.0);
    field->min_height = 100.0 - 0.25 * (double)(height - 1);
    field->max_height = 100.0 + 0.5 * (double)(width - 1);
}

static void test_resample_plane(void **state)
{
    (void)state;
    lk_heightfield plane, resampled;
    lk_error error = {0};
    make_plane(&plane, 37, 23);
    /* 37 -> 65 (2^6 + 1). */
    assert_int_equal(lk_heightfield_resample(&plane, 0, &resampled, &error), LK_OK);
    assert_int_equal(resampled.width, 65);
    assert_int_equal(resampled.height, 65);
    assert_float_equal(resampled.spacing_x, 30.0 * 36.0 / 64.0, 1e-12);
    assert_float_equal(resampled.spacing_y, 12.5 * 22.0 / 64.0, 1e-12);
    for (size_t j = 0; j < 65; j++)
        for (size_t i = 0; i < 65; i++) {
            /* The plane in metres: z = 0.5 x / 30 - 0.25 y / 12.5 + 100. */
            double x = (double)i * resampled.spacing_x, y = (double)j * resampled.spacing_y;
            double expected = 0.5 * x / 30.0 - 0.25 * y / 12.5 + 100.0;
            double got = resampled.heights[j * 65 + i];
            if (fabs(got - expected) > 1e-5) fail_msg("(%zu, %zu): got %.9g, expected %.9g", i, j, got, expected);
        }
    assert_float_equal(resampled.min_height, 100.0 - 0.25 * 22.0, 1e-5);
    assert_float_equal(resampled.max_height, 100.0 + 0.5 * 36.0, 1e-5);
    lk_heightfield_free(&resampled);

    /* Down-sampling a plane is exact too; any size >= 2 is accepted. */
    assert_int_equal(lk_heightfield_resample(&plane, 2, &resampled, &error), LK_OK);
    assert_float_equal(resampled.heights[0], 100.0, 0.0);
    assert_float_equal(resampled.heights[1], 118.0, 1e-5);
    assert_float_equal(resampled.heights[2], 94.5, 1e-5);
    assert_float_equal(resampled.heights[3], 112.5, 1e-5);
    lk_heightfield_free(&resampled);

    /* Exact sizes: 17 stays 17, 18 goes to 33. */
    lk_heightfield small;
    make_plane(&small, 17, 5);
    assert_int_equal(lk_heightfield_resample(&small, 0, &resampled, &error), LK_OK);
    assert_int_equal(resampled.width, 17);
    for (size_t i = 0; i < 17; i++) assert_float_equal(resampled.heights[i], small.heights[i], 1e-5);
    lk_heightfield_free(&resampled);
    lk_heightfield_free(&small);
    make_plane(&small, 3, 18);
    assert_int_equal(lk_heightfield_resample(&small, 0, &resampled, &error), LK_OK);
    assert_int_equal(resampled.width, 33);
    lk_heightfield_free(&resampled);
    lk_heightfield_free(&small);

    assert_int_equal(lk_heightfield_resample(&plane, 1, &resampled, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "size 1");
    assert_int_equal(lk_heightfield_resample(&plane, 5, &plane, &error), LK_ERR_INVALID);
    lk_heightfield_free(&plane);
}

/* ---- PGM ---------------------------------------------------------------- */

static void test_pgm_binary(void **state)
{
    (void)state;
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.image_height_range = 510.0;
    options.z_scale = 2.0;
    options.spacing = 5.0;

    /* 8-bit, 3x2, a comment in the header. Height = sample/255*510*2. */
    static const unsigned char p5_8[] = "P5\n# made by hand\n3 2\n255\n\x00\x10\xff\x80\x01\x02";
    const char *path = lk_test_tmpfile("ramp8.pgm");
    write_file(path, p5_8, sizeof p5_8 - 1);
    lk_heightfield field;
    load_dem(path, &options, &field);
    assert_int_equal(field.width, 3);
    assert_int_equal(field.height, 2);
    assert_float_equal(field.spacing_x, 5.0, 0.0);
    assert_float_equal(field.spacing_y, 5.0, 0.0);
    /* The image's top row is north: it becomes the last row. */
    static const float expected8[] = {0x80 * 4.0f, 1 * 4.0f, 2 * 4.0f, 0.0f, 0x10 * 4.0f, 0xff * 4.0f};
    for (size_t k = 0; k < 6; k++) assert_float_equal(field.heights[k], expected8[k], 1e-3);
    assert_float_equal(field.min_height, 0.0, 0.0);
    assert_float_equal(field.max_height, 1020.0, 1e-3);
    assert_int_equal(field.nodata_count, 0);
    lk_heightfield_free(&field);

    /* 16-bit big-endian, maxval 1000 (> 255 means two bytes per sample). */
    static const unsigned char p5_16[] = "P5 2 2 1000\n\x03\xe8\x00\x00\x01\xf4\x00\x01";
    lk_error error;
    options.image_height_range = 1000.0;
    options.z_scale = 1.0;
    assert_int_equal(read_bytes(p5_16, sizeof p5_16 - 1, "ramp16.pgm", &options, &field, &error), LK_OK);
    assert_float_equal(field.heights[0], 500.0, 1e-4);
    assert_float_equal(field.heights[1], 1.0, 1e-4);
    assert_float_equal(field.heights[2], 1000.0, 1e-4);
    assert_float_equal(field.heights[3], 0.0, 0.0);
    lk_heightfield_free(&field);

    /* A committed 12-bit file (maxval 4095, two bytes per sample). */
    load_dem(lk_test_data("dem/ramp12_p5.pgm"), NULL, &field);
    assert_int_equal(field.width, 3);
    assert_int_equal(field.height, 2);
    static const double expected12[] = {1, 256, 512, 4095, 2048, 0};
    for (size_t k = 0; k < 6; k++) assert_float_equal(field.heights[k], expected12[k] * 1000.0 / 4095.0, 1e-3);
    lk_heightfield_free(&field);

    /* maxval 65535: full 16-bit range. */
    static const unsigned char p5_full[] = "P5\n2 2\n65535\n\xff\xff\x80\x00\x00\x00\x00\x01";
    assert_int_equal(read_bytes(p5_full, sizeof p5_full - 1, "full.pgm", NULL, &field, &error), LK_OK);
    assert_float_equal(field.heights[0], 0.0, 0.0);
    assert_float_equal(field.heights[1], 1000.0 / 65535.0, 1e-6);
    assert_float_equal(field.heights[2], 1000.0, 1e-4);
    assert_float_equal(field.heights[3], 32768.0 * 1000.0 / 65535.0, 1e-3);
    lk_heightfield_free(&field);
}

static void test_pgm_ascii(void **state)
{
    (void)state;
    lk_heightfield field;
    load_dem(lk_test_data("dem/comments_p2.pgm"), NULL, &field);
    assert_int_equal(field.width, 4);
    assert_int_equal(field.height, 3);
    /* maxval 100, range 1000 m: sample * 10 m; file rows bottom-up. */
    static const float expected[] = {800, 900, 950, 1000, 400, 500, 600, 700, 0, 100, 200, 300};
    for (size_t k = 0; k < 12; k++) assert_float_equal(field.heights[k], expected[k], 1e-3);
    assert_float_equal(field.min_height, 0.0, 0.0);
    assert_float_equal(field.max_height, 1000.0, 1e-3);
    assert_float_equal(field.spacing_x, 1.0, 0.0);
    lk_heightfield_free(&field);
}

static void test_pgm_errors(void **state)
{
    (void)state;
    /* Truncated P5: 3x3 needs 9 bytes, 4 present; the message names the
     * byte where the file ends. */
    static const char truncated[] = "P5\n3 3\n255\n\x01\x02\x03\x04";
    expect_bytes_failure(truncated, sizeof truncated - 1, "cut.pgm", LK_ERR_PARSE, "byte 15");
    expect_bytes_failure(truncated, sizeof truncated - 1, "cut.pgm", LK_ERR_PARSE, "truncated");
    /* 16-bit sample cut in half. */
    static const char half[] = "P5 2 2 300\n\x01\x02\x03\x04\x05\x06\x07";
    expect_bytes_failure(half, sizeof half - 1, "half.pgm", LK_ERR_PARSE, "byte 18");
    expect_bytes_failure("P5\n2 2\n0\n\0\0\0\0", 13, "zero.pgm", LK_ERR_PARSE, "zero.pgm:3: maxval 0");
    expect_bytes_failure("P2\n# c\n2 2\n70000\n1 2 3 4\n", 25, "big.pgm", LK_ERR_PARSE, "big.pgm:4: maxval 70000");
    expect_bytes_failure("Q5\n2 2\n255\n\1\2\3\4", 15, "magic.pgm", LK_ERR_PARSE, "byte 0");
    expect_bytes_failure("Q5\n2 2\n255\n\1\2\3\4", 15, "magic.pgm", LK_ERR_PARSE, "'Q5'");
    expect_bytes_failure("P6\n2 2\n255\n", 11, "colour.ppm", LK_ERR_UNSUPPORTED, "P6");
    expect_bytes_failure("P2\n2 2\n9\n1 2\n3 x\n", 17, "text.pgm", LK_ERR_PARSE,
                         "text.pgm:5: expected the sample, got 'x'");
    expect_bytes_failure("P2\n2 2\n9\n1 2\n3\n", 15, "short.pgm", LK_ERR_PARSE, "short.pgm:6");
    expect_bytes_failure("P2\n2 2\n9\n1 2\n3 10\n", 18, "over.pgm", LK_ERR_PARSE, "sample 10 exceeds maxval 9");
    expect_bytes_failure("P5\n2 2\n9\n\1\2\3\12", 13, "over5.pgm", LK_ERR_PARSE, "byte 12: sample 10");
    expect_bytes_failure("P5\n-2 2\n255\n", 12, "neg.pgm", LK_ERR_PARSE, "neg.pgm:2: expected the width, got '-2'");
    expect_bytes_failure("P5\n2", 4, "end.pgm", LK_ERR_PARSE, "expected the height, found the end");
    expect_bytes_failure("P5\n1 1\n255\n\7", 12, "one.pgm", LK_ERR_RANGE, "1x1");
    expect_bytes_failure("P5 99999 99999 255\n", 19, "huge.pgm", LK_ERR_LIMIT, "99999x99999");
    expect_bytes_failure("GIF89a", 6, "image.gif", LK_ERR_UNSUPPORTED, "not a PGM");

    /* Through lk_dem_read: the extension picks our reader, the file name is
     * in the message; a missing file is an I/O error naming the path. */
    const char *path = lk_test_tmpfile("bad.pgm");
    write_file(path, truncated, sizeof truncated - 1);
    expect_dem_failure(path, NULL, LK_ERR_PARSE, "bad.pgm: byte 15");
    expect_dem_failure(lk_test_tmpfile("missing.tif"), NULL, LK_ERR_IO, "missing.tif");
    expect_dem_failure(lk_test_tmpfile("missing.pgm"), NULL, LK_ERR_IO, "cannot open");
    /* The budget applies to our readers too. */
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.max_samples = 5;
    expect_dem_failure(lk_test_data("dem/comments_p2.pgm"), &options, LK_ERR_LIMIT, "budget of 5 samples");
    options.max_samples = 0;
    expect_dem_failure(lk_test_data("dem/comments_p2.pgm"), &options, LK_ERR_INVALID, "max_samples");
}

/* ---- PNG ---------------------------------------------------------------- */

static void test_png(void **state)
{
    (void)state;
    lk_heightfield field;
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.image_height_range = 65535.0; /* one metre per 16-bit step */
    options.spacing = 2.0;
    load_dem(lk_test_data("dem/ramp16.png"), &options, &field);
    assert_int_equal(field.width, 5);
    assert_int_equal(field.height, 4);
    assert_float_equal(field.spacing_y, 2.0, 0.0);
    /* Written as (row*5 + col)*3000 + 7 with row 0 on top. */
    for (size_t j = 0; j < 4; j++)
        for (size_t i = 0; i < 5; i++)
            assert_float_equal(field.heights[j * 5 + i], (double)(((3 - j) * 5 + i) * 3000 + 7), 1e-2);
    assert_float_equal(field.min_height, 7.0, 1e-4);
    assert_float_equal(field.max_height, 57007.0, 1e-2);
    lk_heightfield_free(&field);

    /* RGB with r = g = b is read as grey (k*20 for pixel k, 8-bit). */
    load_dem(lk_test_data("dem/grey_rgb.png"), NULL, &field);
    assert_int_equal(field.width, 4);
    assert_int_equal(field.height, 3);
    assert_float_equal(field.heights[0], 8 * 20 * 1000.0 / 255.0, 1e-3);  /* bottom-left = pixel 8 */
    assert_float_equal(field.heights[11], 3 * 20 * 1000.0 / 255.0, 1e-3); /* top-right = pixel 3 */
    lk_heightfield_free(&field);
    /* Real colour is refused, naming the pixel. */
    expect_dem_failure(lk_test_data("dem/colour.png"), NULL, LK_ERR_UNSUPPORTED, "pixel (1, 1) is (100, 7, 100)");

    /* Grey + alpha: pixel 6 (image x 2, y 1; grey 200) is transparent, so
     * no-data. Pixel k has grey 10 k. It is field (2, 2); its neighbours at
     * distance 1 are pixels 2, 5, 7 and 10, and the tie goes to the lowest
     * field index: field (2, 1) = pixel 10. */
    load_dem(lk_test_data("dem/alpha_hole.png"), NULL, &field);
    assert_int_equal(field.nodata_count, 1);
    assert_float_equal(field.heights[2 * 4 + 2], 100 * 1000.0 / 255.0, 1e-3);
    assert_true(field.max_height < 200 * 1000.0 / 255.0);
    lk_heightfield_free(&field);

    /* A cut PNG fails with libpng's reason and a byte offset. */
    FILE *file = fopen(lk_test_data("dem/ramp16.png"), "rb");
    assert_non_null(file);
    unsigned char bytes[256];
    size_t size = fread(bytes, 1, sizeof bytes, file);
    fclose(file);
    expect_bytes_failure(bytes, size - 30, "cut.png", LK_ERR_PARSE, "cut.png: byte");
    expect_bytes_failure(bytes, 20, "cut.png", LK_ERR_PARSE, "PNG:");
    /* Valid chunks, but the compressed rows stop half way: refused rather
     * than padded. */
    expect_dem_failure(lk_test_data("dem/short_idat.png"), NULL, LK_ERR_PARSE, "Not enough image data");
}

/* ---- GeoTIFFs made with GDAL -------------------------------------------- */

/* Writes a Float32 GeoTIFF; `epsg` 0 leaves the CRS out. */
static void write_geotiff(const char *path, int width, int height, const float *values, const double transform[6],
                          int epsg, const double *nodata, const char *unit, double scale, double offset)
{
    GDALAllRegister();
    GDALDriverH driver = GDALGetDriverByName("GTiff");
    assert_non_null(driver);
    GDALDatasetH dataset = GDALCreate(driver, path, width, height, 1, GDT_Float32, NULL);
    assert_non_null(dataset);
    assert_int_equal(GDALSetGeoTransform(dataset, (double *)transform), CE_None);
    if (epsg) {
        OGRSpatialReferenceH srs = OSRNewSpatialReference(NULL);
        assert_int_equal(OSRImportFromEPSG(srs, epsg), OGRERR_NONE);
        assert_int_equal(GDALSetSpatialRef(dataset, srs), CE_None);
        OSRDestroySpatialReference(srs);
    }
    GDALRasterBandH band = GDALGetRasterBand(dataset, 1);
    if (nodata) assert_int_equal(GDALSetRasterNoDataValue(band, *nodata), CE_None);
    if (unit) assert_int_equal(GDALSetRasterUnitType(band, unit), CE_None);
    if (scale != 1.0 || offset != 0.0) {
        assert_int_equal(GDALSetRasterScale(band, scale), CE_None);
        assert_int_equal(GDALSetRasterOffset(band, offset), CE_None);
    }
    assert_int_equal(
        GDALRasterIO(band, GF_Write, 0, 0, width, height, (void *)values, width, height, GDT_Float32, 0, 0), CE_None);
    GDALClose(dataset);
}

static void test_geotiff_nodata(void **state)
{
    (void)state;
    enum { W = 20, H = 10 };
    float values[W * H];
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) values[r * W + c] = (float)(100 * r + c);
    /* A hole of three cells in file row 4, a NaN, and a no-data corner. */
    values[4 * W + 5] = values[4 * W + 6] = values[4 * W + 7] = -9999.0f;
    values[0] = -9999.0f;
    values[7 * W + 12] = NAN;
    double transform[6] = {500000.0, 10.0, 0.0, 4000000.0, 0.0, -30.0};
    double nodata = -9999.0;
    const char *path = lk_test_tmpfile("hole.tif");
    write_geotiff(path, W, H, values, transform, 32633, &nodata, NULL, 1.0, 0.0);

    lk_heightfield field;
    load_dem(path, NULL, &field);
    assert_int_equal(field.width, W);
    assert_int_equal(field.height, H);
    assert_int_equal(field.nodata_count, 5);
    assert_all_finite(&field);
    assert_float_equal(field.spacing_x, 10.0, 0.0);
    assert_float_equal(field.spacing_y, 30.0, 0.0);
    assert_float_equal(field.origin_x, 500005.0, 1e-9);
    assert_float_equal(field.origin_y, 4000000.0 - 300.0 + 15.0, 1e-9);
    /* File row r is field row H-1-r. Cells 10 m apart in x, 30 m in y:
     * the nearest valid cells lie along the row. */
#define AT(c, r) field.heights[(H - 1 - (r)) * W + (c)]
    assert_float_equal(AT(5, 4), 404.0, 0.0);  /* 10 m to column 4 */
    assert_float_equal(AT(6, 4), 404.0, 0.0);  /* 20 m both ways: the tie goes to the lower index */
    assert_float_equal(AT(7, 4), 408.0, 0.0);  /* 10 m to column 8 */
    assert_float_equal(AT(0, 0), 1.0, 0.0);    /* corner from its right-hand neighbour */
    assert_float_equal(AT(12, 7), 711.0, 0.0); /* NaN counts as no-data */
#undef AT
    assert_float_equal(field.min_height, 1.0, 0.0);
    assert_float_equal(field.max_height, 919.0, 0.0);
    lk_heightfield_free(&field);

    /* Every sample no-data: refused. */
    for (int k = 0; k < W * H; k++) values[k] = -9999.0f;
    path = lk_test_tmpfile("empty.tif");
    write_geotiff(path, W, H, values, transform, 32633, &nodata, NULL, 1.0, 0.0);
    expect_dem_failure(path, NULL, LK_ERR_RANGE, "no valid heights");
    /* Band 2 of a one-band file. */
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.band = 2;
    expect_dem_failure(path, &options, LK_ERR_INVALID, "band 2 requested but the file has 1 band");

    /* A rotated geotransform is refused. */
    double rotated[6] = {500000.0, 10.0, 2.0, 4000000.0, 1.0, -30.0};
    path = lk_test_tmpfile("rotated.tif");
    write_geotiff(path, W, H, values, rotated, 32633, NULL, NULL, 1.0, 0.0);
    expect_dem_failure(path, NULL, LK_ERR_UNSUPPORTED, "rotated");

    /* A 1-row grid cannot make a surface. */
    path = lk_test_tmpfile("row.tif");
    write_geotiff(path, W, 1, values, transform, 32633, NULL, NULL, 1.0, 0.0);
    expect_dem_failure(path, NULL, LK_ERR_RANGE, "20x1 grid is too small");

    /* Something GDAL cannot read. */
    path = lk_test_tmpfile("rubbish.dat");
    write_file(path, "this is not a raster\n", 21);
    expect_dem_failure(path, NULL, LK_ERR_UNSUPPORTED, "rubbish.dat: not a raster format GDAL can read");
    /* GDAL's words in one form, without its own quoting of the path. */
    expect_dem_failure(path, NULL, LK_ERR_UNSUPPORTED,
                       "rubbish.dat: not a raster format GDAL can read (GDAL: not recognized as a supported file "
                       "format)");
}

/* The fill takes each hole's height from the nearest valid sample: compared
 * with a brute-force search on a grid with 97% holes (seeded), the two-pass
 * propagation must be exact nearly everywhere and never much farther. */
static void test_nodata_fill_nearest(void **state)
{
    (void)state;
    enum { W = 64, H = 48 };
    static float values[W * H];
    static unsigned char valid[W * H];
    uint64_t seed = 12345;
    size_t valid_count = 0;
    for (int k = 0; k < W * H; k++) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        valid[k] = (seed >> 33) % 100 < 3;
        valid_count += valid[k];
        values[k] = valid[k] ? (float)k : -1.0f; /* a valid height names its cell */
    }
    double transform[6] = {0.0, 1.0, 0.0, 1000.0, 0.0, -1.0}; /* square metre cells, no CRS */
    double nodata = -1.0;
    const char *path = lk_test_tmpfile("sparse.tif");
    write_geotiff(path, W, H, values, transform, 0, &nodata, NULL, 1.0, 0.0);
    lk_heightfield field;
    load_dem(path, NULL, &field);
    assert_int_equal(field.nodata_count, W * H - valid_count);
    size_t exact = 0, holes = 0;
    double worst = 1.0;
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            int row = H - 1 - j; /* file row */
            if (valid[row * W + i]) {
                assert_float_equal(field.heights[j * W + i], values[row * W + i], 0.0);
                continue;
            }
            holes++;
            int source = (int)field.heights[j * W + i];
            assert_true(source >= 0 && source < W * H && valid[source]);
            double used = hypot(source % W - i, source / W - row), best = INFINITY;
            for (int k = 0; k < W * H; k++)
                if (valid[k]) best = fmin(best, hypot(k % W - i, k / W - row));
            if (used <= best + 1e-9)
                exact++;
            else
                worst = fmax(worst, used / best);
        }
    print_message("fill: %zu holes, %zu exactly nearest, worst distance ratio %.4f\n", holes, exact, worst);
    assert_true(exact >= holes * 99 / 100);
    assert_true(worst < 1.1);
    lk_heightfield_free(&field);
}

static void test_geotiff_units(void **state)
{
    (void)state;
    float values[4 * 3];
    for (int k = 0; k < 12; k++) values[k] = (float)(100 + k);
    double transform[6] = {300000.0, 25.0, 0.0, 5000000.0, 0.0, -25.0};
    const char *path = lk_test_tmpfile("feet.tif");
    /* Stored value v means (2 v + 10) feet. */
    write_geotiff(path, 4, 3, values, transform, 32633, NULL, "ft", 2.0, 10.0);
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.z_scale = 3.0;
    lk_heightfield field;
    load_dem(path, &options, &field);
    /* Field (0, 0) is file row 2, column 0: v = 108. */
    assert_float_equal(field.heights[0], (2.0 * 108.0 + 10.0) * 0.3048 * 3.0, 1e-3);
    assert_float_equal(field.heights[11], (2.0 * 103.0 + 10.0) * 0.3048 * 3.0, 1e-3);
    assert_float_equal(field.min_height, 210.0 * 0.3048 * 3.0, 1e-3);
    assert_float_equal(field.max_height, 232.0 * 0.3048 * 3.0, 1e-3);
    lk_heightfield_free(&field);

    /* Metres: no conversion. */
    path = lk_test_tmpfile("metre.tif");
    write_geotiff(path, 4, 3, values, transform, 32633, NULL, "metre", 1.0, 0.0);
    load_dem(path, NULL, &field);
    assert_float_equal(field.heights[0], 108.0, 0.0);
    lk_heightfield_free(&field);
}

static void test_geotiff_geographic(void **state)
{
    (void)state;
    float values[6 * 5];
    for (int k = 0; k < 30; k++) values[k] = (float)k;
    /* WGS84 degrees, 0.01 deg cells, rows from 60.05 N down to 60.0 N:
     * cell centres 60.005..60.045, mean latitude 60.025. */
    double transform[6] = {10.0, 0.01, 0.0, 60.05, 0.0, -0.01};
    const char *path = lk_test_tmpfile("geographic.tif");
    write_geotiff(path, 6, 5, values, transform, 4326, NULL, NULL, 1.0, 0.0);
    lk_heightfield field;
    load_dem(path, NULL, &field);
    double per_lon, per_lat;
    wgs84_metres_per_degree(60.025, &per_lon, &per_lat);
    assert_float_equal(field.spacing_x, 0.01 * per_lon, 1e-6);
    assert_float_equal(field.spacing_y, 0.01 * per_lat, 1e-6);
    assert_float_equal(field.spacing_x, 557.6, 0.5); /* about half the equatorial value */
    assert_float_equal(field.spacing_y, 1114.1, 0.5);
    lk_heightfield_free(&field);

    /* No CRS and metre-sized cells near the origin: not mistaken for degrees. */
    double local[6] = {0.0, 2.0, 0.0, 10.0, 0.0, -2.0};
    path = lk_test_tmpfile("local.tif");
    write_geotiff(path, 6, 5, values, local, 0, NULL, NULL, 1.0, 0.0);
    load_dem(path, NULL, &field);
    assert_float_equal(field.spacing_x, 2.0, 0.0);
    assert_float_equal(field.origin_y, 1.0, 0.0);
    lk_heightfield_free(&field);
}

/* The synthetic terrain: deterministic, real min/max, bad sizes refused. */
/* ---- jacksboro_fault_dem.npz (NumPy archive, our own reader) ------------ */

static void test_npz_jacksboro(void **state)
{
    (void)state;
    lk_heightfield field;
    load_dem(lk_test_sample("jacksboro_fault_dem.npz"), NULL, &field);
    /* elevation.npy is int16 (344, 403): 344 rows of 403 samples. */
    assert_int_equal(field.width, 403);
    assert_int_equal(field.height, 344);
    assert_int_equal(field.nodata_count, 0);
    assert_float_equal(field.min_height, 236.0, 0.0);
    assert_float_equal(field.max_height, 1076.0, 0.0);
    /* The first stored row is north: its first sample (483 m) is the
     * north-west corner, the last stored sample (272 m) the south-east. */
    assert_float_equal(field.heights[(field.height - 1) * field.width], 483.0, 0.0);
    assert_float_equal(field.heights[field.width - 1], 272.0, 0.0);
    /* 3 arc-second cells converted at the mean latitude (36.5896 deg). */
    double south = 36.44625 + 0.5 / 1200.0, per_lon, per_lat;
    wgs84_metres_per_degree(south + 0.5 / 1200.0 * 343.0, &per_lon, &per_lat);
    assert_float_equal(field.spacing_x, per_lon / 1200.0, 1e-6);
    assert_float_equal(field.spacing_y, per_lat / 1200.0, 1e-6);
    assert_true(field.spacing_x > 74.0 && field.spacing_x < 75.0);
    assert_float_equal(field.origin_x, (-84.41375 + 0.5 / 1200.0) * per_lon, 1e-3);
    assert_float_equal(field.origin_y, south * per_lat, 1e-3);

    /* The same bytes through the in-memory entry point; then every cut of
     * the archive fails cleanly (ASan checks the reads). */
    char *bytes = NULL;
    size_t size = 0;
    lk_error error = {0};
    assert_int_equal(lk__read_file(lk_test_sample("jacksboro_fault_dem.npz"), 0, &bytes, &size, &error), LK_OK);
    lk_heightfield copy;
    assert_int_equal(read_bytes(bytes, size, "jacksboro.npz", NULL, &copy, &error), LK_OK);
    assert_memory_equal(copy.heights, field.heights, field.width * field.height * sizeof(float));
    lk_heightfield_free(&copy);
    for (size_t cut = 0; cut < size; cut += cut < 64 ? 1 : 1531) {
        lk_status status = read_bytes(bytes, cut, "cut.npz", NULL, &copy, &error);
        if (status == LK_OK) fail_msg("an archive cut at byte %zu was accepted", cut);
        assert_null(copy.heights);
    }
    /* A budget smaller than the grid is refused before allocating it. */
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.max_samples = 100000;
    assert_int_equal(read_bytes(bytes, size, "small.npz", &options, &copy, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "403x344");
    /* A corrupted deflate stream names the member. */
    bytes[200] ^= 0x55;
    bytes[201] ^= 0xff;
    lk_status status = read_bytes(bytes, size, "flipped.npz", NULL, &copy, &error);
    if (status == LK_OK)
        lk_heightfield_free(&copy);
    else
        lk_assert_message_contains(error, "flipped.npz");
    free(bytes);
    expect_bytes_failure("PK\x03\x04 not really", 16, "junk.npz", LK_ERR_PARSE, "not a zip archive");
    lk_heightfield_free(&field);
}

static void test_fractal(void **state)
{
    (void)state;
    lk_heightfield a, b;
    lk_error error = {0};
    assert_int_equal(lk_heightfield_fractal(65, 30.0, &a, &error), LK_OK);
    assert_int_equal(lk_heightfield_fractal(65, 30.0, &b, &error), LK_OK);
    assert_memory_equal(a.heights, b.heights, 65 * 65 * sizeof(float));
    float lo = a.heights[0], hi = a.heights[0];
    for (size_t k = 0; k < 65 * 65; k++) {
        lo = a.heights[k] < lo ? a.heights[k] : lo;
        hi = a.heights[k] > hi ? a.heights[k] : hi;
    }
    assert_true(fabs(a.min_height - lo) < 1e-3 && fabs(a.max_height - hi) < 1e-3);
    assert_true(hi - lo > 300 && hi - lo < 2000); /* about 2 km of relief at most */
    assert_true(a.spacing_x == 30.0 && a.width == 65 && a.height == 65);
    lk_heightfield_free(&a);
    lk_heightfield_free(&b);
    assert_int_equal(lk_heightfield_fractal(1, 30.0, &a, &error), LK_ERR_INVALID);
    assert_int_equal(lk_heightfield_fractal(65, 0.0, &a, &error), LK_ERR_INVALID);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_etopo20),
        cmocka_unit_test(test_etopo20_resample),
        cmocka_unit_test(test_resample_plane),
        cmocka_unit_test(test_pgm_binary),
        cmocka_unit_test(test_pgm_ascii),
        cmocka_unit_test(test_pgm_errors),
        cmocka_unit_test(test_png),
        cmocka_unit_test(test_geotiff_nodata),
        cmocka_unit_test(test_nodata_fill_nearest),
        cmocka_unit_test(test_geotiff_units),
        cmocka_unit_test(test_geotiff_geographic),
        cmocka_unit_test(test_fractal),
        cmocka_unit_test(test_npz_jacksboro),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
