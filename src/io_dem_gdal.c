/* SPDX-License-Identifier: MIT */
/* GDAL loaded on first use (see src/io_dem_gdal.h for why): dlopen of the
 * library lodkit was built against, by its soname (LK_GDAL_SONAME, which
 * CMakeLists.txt reads from the library pkg-config names), and dlsym of
 * each function of the table. */
#include "io_dem_gdal.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef LK_GDAL_SONAME
#define LK_GDAL_SONAME "libgdal.so"
#endif

static pthread_once_t gdal_once = PTHREAD_ONCE_INIT;
static lk__gdal_api gdal_api;
static bool gdal_loaded;
static char gdal_library[256];
static char gdal_failure[200]; /* why it could not be loaded */

static void gdal_load(void)
{
    const char *library = getenv("LODKIT_GDAL_LIBRARY");
    if (!library || !library[0]) library = LK_GDAL_SONAME;
    snprintf(gdal_library, sizeof gdal_library, "%s", library);
    /* Never closed: GDAL's drivers and caches live as long as the process. */
    void *handle = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char *why = dlerror();
        snprintf(gdal_failure, sizeof gdal_failure, "%s", why ? why : "dlopen failed");
        return;
    }
    /* dlsym returns an object pointer; POSIX guarantees that a function's
     * address survives the copy into a function pointer of its type. */
#define LK__GDAL_RESOLVE(function)                                                                                     \
    {                                                                                                                  \
        void *symbol = dlsym(handle, #function);                                                                       \
        if (!symbol) {                                                                                                 \
            snprintf(gdal_failure, sizeof gdal_failure, "it has no function %s", #function);                           \
            return;                                                                                                    \
        }                                                                                                              \
        memcpy(&gdal_api.function, &symbol, sizeof symbol);                                                            \
    }
    LK__GDAL_FUNCTIONS(LK__GDAL_RESOLVE)
#undef LK__GDAL_RESOLVE
    gdal_api.GDALAllRegister();
    gdal_loaded = true;
}

const lk__gdal_api *lk__gdal_api_load(const char *name, lk_error *error)
{
    _Static_assert(sizeof(void *) == sizeof(void (*)(void)), "function pointers are copied from dlsym's result");
    pthread_once(&gdal_once, gdal_load);
    if (gdal_loaded) return &gdal_api;
    /* Debian names a library's package after its soname: libgdal.so.32 is in libgdal32. */
    char package[64] = "libgdal";
    const char *version = strstr(LK_GDAL_SONAME, ".so.");
    if (version) snprintf(package, sizeof package, "libgdal%s", version + 4);
    lk_error_set(error, LK_ERR_UNSUPPORTED,
                 "%s: reading this grid needs GDAL, which could not be loaded from %s (%s); install GDAL's library "
                 "(Debian package %s) or name it in LODKIT_GDAL_LIBRARY",
                 name, gdal_library, gdal_failure, package);
    return NULL;
}
