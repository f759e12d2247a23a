/* SPDX-License-Identifier: MIT */
/* GDAL for the elevation grid reader (src/io_dem.c), loaded the first time
 * a grid needs it (src/io_dem_gdal.c). GDAL's library pulls in about a
 * hundred others (PROJ, GEOS, HDF5, netCDF, curl, ...): linked into lodkit,
 * their loading cost every command and every program using lodkit-dem some
 * 140 ms at start, whether it read a grid or not. The functions are taken
 * from the library at run time through this table; gdal.h still gives
 * their types and constants. Not installed. */
#ifndef LODKIT_IO_DEM_GDAL_H
#define LODKIT_IO_DEM_GDAL_H

#include "internal.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal.h>
#include <ogr_srs_api.h>

/* Every GDAL function src/io_dem.c calls (or passes, CPLQuietErrorHandler). */
#define LK__GDAL_FUNCTIONS(X)                                                                                          \
    X(GDALAllRegister)                                                                                                 \
    X(GDALOpenEx)                                                                                                      \
    X(GDALIdentifyDriverEx)                                                                                            \
    X(GDALGetDriverShortName)                                                                                          \
    X(GDALGetDriverLongName)                                                                                           \
    X(GDALClose)                                                                                                       \
    X(GDALGetMetadata)                                                                                                 \
    X(GDALGetRasterCount)                                                                                              \
    X(GDALGetRasterXSize)                                                                                              \
    X(GDALGetRasterYSize)                                                                                              \
    X(GDALGetGeoTransform)                                                                                             \
    X(GDALGetSpatialRef)                                                                                               \
    X(GDALGetRasterBand)                                                                                               \
    X(GDALGetRasterNoDataValue)                                                                                        \
    X(GDALGetRasterScale)                                                                                              \
    X(GDALGetRasterOffset)                                                                                             \
    X(GDALGetRasterUnitType)                                                                                           \
    X(GDALRasterIOEx)                                                                                                  \
    X(OSRIsGeographic)                                                                                                 \
    X(CPLErrorReset)                                                                                                   \
    X(CPLGetLastErrorMsg)                                                                                              \
    X(CPLPushErrorHandler)                                                                                             \
    X(CPLPopErrorHandler)                                                                                              \
    X(CPLQuietErrorHandler)                                                                                            \
    X(CPLGetThreadLocalConfigOption)                                                                                   \
    X(CPLSetThreadLocalConfigOption)                                                                                   \
    X(CSLFindString)

/* One pointer per function, named and typed as gdal.h declares it. */
typedef struct lk__gdal_api {
#define LK__GDAL_MEMBER(function) __typeof__(&function) function;
    LK__GDAL_FUNCTIONS(LK__GDAL_MEMBER)
#undef LK__GDAL_MEMBER
} lk__gdal_api;

/* GDAL's functions, its drivers registered; loaded once per process (thread
 * safe), from the library named by the environment variable
 * LODKIT_GDAL_LIBRARY if set, else the one lodkit was built against (its
 * soname, e.g. libgdal.so.32). NULL when it cannot be loaded, with *error
 * saying so for the grid `name` (LK_ERR_UNSUPPORTED). */
const lk__gdal_api *lk__gdal_api_load(const char *name, lk_error *error);

#endif
