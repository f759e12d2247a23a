/* SPDX-License-Identifier: MIT */
/* Offscreen OpenGL ES 2.0 context: surfaceless EGL on Mesa, one framebuffer
 * object per renderer, shader programs compiled on first use. */
/* dl_iterate_phdr and struct dl_phdr_info are GNU extensions of <link.h>. */
#define _GNU_SOURCE 1

#include <dlfcn.h>
#include <link.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"

#include <EGL/eglext.h>

#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif
#ifndef EGL_NO_CONFIG_KHR
#define EGL_NO_CONFIG_KHR ((EGLConfig)0)
#endif

#define LK__MAX_RENDER_SIZE 8192u

/* What to install when EGL or GLES2 is not usable (Debian package names). */
#define LK__GL_PACKAGES                                                                                                \
    "offscreen rendering needs Mesa's EGL and GLES2 drivers (Debian: apt-get install libegl-mesa0 "                    \
    "libgl1-mesa-dri libgles2)"

/* EGL shares one display object between everyone who asks for the default
 * surfaceless display, and eglTerminate tears it down for all of them
 * (EGL_KHR_display_reference is not in Mesa 22). Renderers alive at the
 * same time therefore count their users of the display and only the last
 * one terminates it. This is the only process-wide state of lodkit: the
 * display is process-wide by EGL's design. */
static pthread_mutex_t display_mutex = PTHREAD_MUTEX_INITIALIZER;
static size_t display_users;

/* Mesa unloads its DRI driver at eglTerminate; LeakSanitizer (and valgrind)
 * then cannot symbolise the driver's one-time allocations and report them
 * as leaks "in unknown module". Opening the already-loaded driver again with
 * RTLD_NODELETE keeps it mapped until exit, which is harmless outside
 * sanitizer builds too, so it is always done. */
static int keep_driver_loaded(struct dl_phdr_info *info, size_t size, void *user)
{
    (void)size;
    (void)user;
    const char *name = info->dlpi_name;
    if (!name || !*name) return 0;
    size_t length = strlen(name);
    static const char suffix[] = "_dri.so";
    int is_driver = length >= sizeof suffix - 1 && strcmp(name + length - (sizeof suffix - 1), suffix) == 0;
    if (!is_driver && strstr(name, "libgallium")) is_driver = 1; /* newer Mesa: one gallium library */
    if (is_driver) {
        /* The handle is deliberately never closed: RTLD_NODELETE pins the
         * library regardless, and this reference costs nothing. */
        void *handle = dlopen(name, RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);
        (void)handle;
    }
    return 0;
}

static const char *egl_error_name(EGLint code)
{
    switch (code) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "unknown EGL error";
    }
}

static int has_extension(const char *list, const char *name)
{
    if (!list) return 0;
    size_t length = strlen(name);
    for (const char *p = list; (p = strstr(p, name)) != NULL; p += length) {
        int starts = p == list || p[-1] == ' ';
        int ends = p[length] == '\0' || p[length] == ' ';
        if (starts && ends) return 1;
    }
    return 0;
}

static lk_status make_current(const lk_renderer *renderer, lk_error *error)
{
    if (eglGetCurrentContext() == renderer->context && eglGetCurrentDisplay() == renderer->display) return LK_OK;
    if (!eglMakeCurrent(renderer->display, EGL_NO_SURFACE, EGL_NO_SURFACE, renderer->context))
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "eglMakeCurrent failed (%s): the renderer's context may be current in another thread",
                            egl_error_name(eglGetError()));
    return LK_OK;
}

lk_status lk__gl_check(const char *what, lk_error *error)
{
    GLenum code = glGetError();
    if (code == GL_NO_ERROR) return LK_OK;
    /* Drain the remaining flags so the next check starts clean. */
    for (int i = 0; i < 16 && glGetError() != GL_NO_ERROR; i++) {
    }
    const char *name = code == GL_INVALID_ENUM                    ? "GL_INVALID_ENUM"
                       : code == GL_INVALID_VALUE                 ? "GL_INVALID_VALUE"
                       : code == GL_INVALID_OPERATION             ? "GL_INVALID_OPERATION"
                       : code == GL_OUT_OF_MEMORY                 ? "GL_OUT_OF_MEMORY"
                       : code == GL_INVALID_FRAMEBUFFER_OPERATION ? "GL_INVALID_FRAMEBUFFER_OPERATION"
                                                                  : "unknown GL error";
    return lk_error_set(error, code == GL_OUT_OF_MEMORY ? LK_ERR_NOMEM : LK_ERR_UNSUPPORTED,
                        "OpenGL ES error in %s: %s (0x%04x)", what, name, (unsigned)code);
}

lk_status lk__gl_begin(lk_renderer *renderer, lk_error *error)
{
    if (!renderer) return lk_error_set(error, LK_ERR_INVALID, "no renderer");
    lk_status status = make_current(renderer, error);
    if (status != LK_OK) return status;
    glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
    glViewport(0, 0, (GLsizei)renderer->width, (GLsizei)renderer->height);
    return lk__gl_check("binding the framebuffer", error);
}

/* Looks a shader up by its file name; "mesh.vert" also finds
 * "mesh.vert.glsl" (the files are named *.glsl so the build globs them). */
static const char *shader_text(const char *name)
{
    const char *text = lk__shader_source(name);
    if (text) return text;
    char with_suffix[128];
    int written = snprintf(with_suffix, sizeof with_suffix, "%s.glsl", name);
    if (written <= 0 || (size_t)written >= sizeof with_suffix) return NULL;
    return lk__shader_source(with_suffix);
}

int lk__gl_has_extension(const char *name)
{
    const char *list = (const char *)glGetString(GL_EXTENSIONS);
    if (!list) return 0;
    size_t length = strlen(name);
    /* a whole word of the space-separated list, not a prefix of a longer name */
    for (const char *p = list; (p = strstr(p, name)) != NULL; p += length)
        if ((p == list || p[-1] == ' ') && (p[length] == '\0' || p[length] == ' ')) return 1;
    return 0;
}

/* GLSL ES 1.00 has no include, so shaders share code (lighting.glsl) with a
 * line `#include "NAME"` that is replaced here by that embedded file before
 * compiling; the web viewer expands it the same way. One level deep, a few
 * per shader: the source goes to GL as segments, no copy. */
enum { MAX_SHADER_SEGMENTS = 9 };

static lk_status shader_segments(const char *name, const char **segments, GLint *lengths, GLsizei *count,
                                 lk_error *error)
{
    const char *text = shader_text(name);
    if (!text) return lk_error_set(error, LK_ERR_UNSUPPORTED, "shader %s is not embedded in this build", name);
    static const char directive[] = "#include \"";
    GLsizei segment_count = 0;
    const char *rest = text, *search = text;
    for (;;) {
        const char *found = strstr(search, directive);
        if (!found) break;
        if (found != text && found[-1] != '\n') { /* not at the start of a line */
            search = found + 1;
            continue;
        }
        const char *included_name = found + sizeof directive - 1;
        const char *name_end = strchr(included_name, '"');
        char buffer[64];
        if (!name_end || (size_t)(name_end - included_name) >= sizeof buffer)
            return lk_error_set(error, LK_ERR_UNSUPPORTED, "shader %s: malformed #include", name);
        memcpy(buffer, included_name, (size_t)(name_end - included_name));
        buffer[name_end - included_name] = '\0';
        const char *included = shader_text(buffer);
        if (!included)
            return lk_error_set(error, LK_ERR_UNSUPPORTED, "shader %s includes %s, which is not embedded", name,
                                buffer);
        if (segment_count + 3 > MAX_SHADER_SEGMENTS)
            return lk_error_set(error, LK_ERR_UNSUPPORTED, "shader %s: too many #include lines", name);
        segments[segment_count] = rest;
        lengths[segment_count++] = (GLint)(found - rest);
        segments[segment_count] = included;
        lengths[segment_count++] = (GLint)strlen(included);
        const char *line_end = strchr(name_end, '\n');
        rest = search = line_end ? line_end + 1 : name_end + 1;
    }
    segments[segment_count] = rest;
    lengths[segment_count++] = (GLint)strlen(rest);
    *count = segment_count;
    return LK_OK;
}

static lk_status compile_shader(GLenum type, const char *name, GLuint *shader, lk_error *error)
{
    const char *segments[MAX_SHADER_SEGMENTS];
    GLint lengths[MAX_SHADER_SEGMENTS];
    GLsizei segment_count = 0;
    lk_status status = shader_segments(name, segments, lengths, &segment_count, error);
    if (status != LK_OK) return status;
    GLuint object = glCreateShader(type);
    if (!object) return lk_error_set(error, LK_ERR_UNSUPPORTED, "glCreateShader failed for %s", name);
    glShaderSource(object, segment_count, segments, lengths);
    glCompileShader(object);
    GLint compiled = GL_FALSE;
    glGetShaderiv(object, GL_COMPILE_STATUS, &compiled);
    if (!compiled) {
        char log[400] = "";
        glGetShaderInfoLog(object, (GLsizei)sizeof log, NULL, log);
        glDeleteShader(object);
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "compiling shader %s failed: %s", name, log);
    }
    *shader = object;
    return LK_OK;
}

lk_status lk__gl_program(lk_renderer *renderer, lk__program which, const char *vertex_shader,
                         const char *fragment_shader, const char *const *attributes, GLuint *program, lk_error *error)
{
    if (!renderer || (int)which < 0 || which >= LK__PROGRAM_COUNT || !vertex_shader || !fragment_shader)
        return lk_error_set(error, LK_ERR_INVALID, "lk__gl_program: bad arguments");
    if (renderer->programs[which]) {
        *program = renderer->programs[which];
        return LK_OK;
    }
    lk_status status = make_current(renderer, error);
    if (status != LK_OK) return status;
    GLuint vertex = 0, fragment = 0;
    status = compile_shader(GL_VERTEX_SHADER, vertex_shader, &vertex, error);
    if (status != LK_OK) return status;
    status = compile_shader(GL_FRAGMENT_SHADER, fragment_shader, &fragment, error);
    if (status != LK_OK) {
        glDeleteShader(vertex);
        return status;
    }
    GLuint object = glCreateProgram();
    if (!object) {
        glDeleteShader(vertex);
        glDeleteShader(fragment);
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "glCreateProgram failed");
    }
    glAttachShader(object, vertex);
    glAttachShader(object, fragment);
    for (GLuint location = 0; attributes && attributes[location]; location++)
        glBindAttribLocation(object, location, attributes[location]);
    glLinkProgram(object);
    /* The program keeps what it needs; the shader objects go away with it. */
    glDetachShader(object, vertex);
    glDetachShader(object, fragment);
    glDeleteShader(vertex);
    glDeleteShader(fragment);
    GLint linked = GL_FALSE;
    glGetProgramiv(object, GL_LINK_STATUS, &linked);
    if (!linked) {
        char log[400] = "";
        glGetProgramInfoLog(object, (GLsizei)sizeof log, NULL, log);
        glDeleteProgram(object);
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "linking %s + %s failed: %s", vertex_shader, fragment_shader,
                            log);
    }
    status = lk__gl_check("building a shader program", error);
    if (status != LK_OK) {
        glDeleteProgram(object);
        return status;
    }
    renderer->programs[which] = object;
    *program = object;
    return LK_OK;
}

/* Releases the display reference taken by a successful eglInitialize. */
static void release_display(EGLDisplay display)
{
    pthread_mutex_lock(&display_mutex);
    if (display_users > 0 && --display_users == 0) {
        eglTerminate(display);
        /* Frees EGL's per-thread state of this thread (otherwise reported
         * as a leak at exit). */
        eglReleaseThread();
    }
    pthread_mutex_unlock(&display_mutex);
}

void lk_renderer_free(lk_renderer *renderer)
{
    if (!renderer) return;
    if (renderer->context != EGL_NO_CONTEXT) {
        int current = make_current(renderer, NULL) == LK_OK;
        /* Without our context (current in another thread), release
         * whichever is current here so that GL calls below do nothing
         * rather than touch another renderer's objects. */
        if (!current) eglMakeCurrent(renderer->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        /* Called even without the context so that the splat state's own
         * memory is released. */
        if (renderer->splat_state_free) renderer->splat_state_free(renderer);
        renderer->splat_state_free = NULL;
        if (current) {
            for (int i = 0; i < LK__PROGRAM_COUNT; i++)
                if (renderer->programs[i]) glDeleteProgram(renderer->programs[i]);
            glBindFramebuffer(GL_FRAMEBUFFER, 0);
            if (renderer->framebuffer) glDeleteFramebuffers(1, &renderer->framebuffer);
            if (renderer->color_buffer) glDeleteRenderbuffers(1, &renderer->color_buffer);
            if (renderer->depth_buffer) glDeleteRenderbuffers(1, &renderer->depth_buffer);
            glFinish();
            eglMakeCurrent(renderer->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        }
        eglDestroyContext(renderer->display, renderer->context);
    }
    if (renderer->display != EGL_NO_DISPLAY) release_display(renderer->display);
    free(renderer);
}

/* Creates the framebuffer object: RGBA8 (GL_OES_rgb8_rgba8) or RGBA4 colour,
 * 24-bit depth (GL_OES_depth24) or 16-bit. */
static lk_status create_framebuffer(lk_renderer *renderer, lk_error *error)
{
    const char *extensions = (const char *)glGetString(GL_EXTENSIONS);
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
    GLint max_viewport[2] = {0, 0};
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_viewport);
    if (max_viewport[0] > 0 && max_viewport[0] < max_size) max_size = max_viewport[0];
    if (max_viewport[1] > 0 && max_viewport[1] < max_size) max_size = max_viewport[1];
    if (max_size > 0 && (renderer->width > (unsigned)max_size || renderer->height > (unsigned)max_size))
        return lk_error_set(error, LK_ERR_INVALID, "image size %ux%u exceeds this driver's limit of %d pixels a side",
                            renderer->width, renderer->height, (int)max_size);
    GLenum color_format = has_extension(extensions, "GL_OES_rgb8_rgba8") ? GL_RGBA8_OES : GL_RGBA4;
    GLenum depth_format = has_extension(extensions, "GL_OES_depth24") ? GL_DEPTH_COMPONENT24_OES : GL_DEPTH_COMPONENT16;

    glGenFramebuffers(1, &renderer->framebuffer);
    glGenRenderbuffers(1, &renderer->color_buffer);
    glGenRenderbuffers(1, &renderer->depth_buffer);
    glBindRenderbuffer(GL_RENDERBUFFER, renderer->color_buffer);
    glRenderbufferStorage(GL_RENDERBUFFER, color_format, (GLsizei)renderer->width, (GLsizei)renderer->height);
    glBindRenderbuffer(GL_RENDERBUFFER, renderer->depth_buffer);
    glRenderbufferStorage(GL_RENDERBUFFER, depth_format, (GLsizei)renderer->width, (GLsizei)renderer->height);
    glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, renderer->color_buffer);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, renderer->depth_buffer);
    lk_status status = lk__gl_check("creating the framebuffer", error);
    if (status != LK_OK) return status;
    GLenum complete = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (complete != GL_FRAMEBUFFER_COMPLETE)
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "the %ux%u framebuffer is incomplete (status 0x%04x)",
                            renderer->width, renderer->height, (unsigned)complete);
    glGetIntegerv(GL_ALIASED_POINT_SIZE_RANGE, renderer->point_size_range);
    glViewport(0, 0, (GLsizei)renderer->width, (GLsizei)renderer->height);
    return lk__gl_check("creating the framebuffer", error);
}

lk_status lk_renderer_create(unsigned width, unsigned height, lk_renderer **out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_renderer_create: out is NULL");
    *out = NULL;
    if (width < 1 || height < 1 || width > LK__MAX_RENDER_SIZE || height > LK__MAX_RENDER_SIZE)
        return lk_error_set(error, LK_ERR_INVALID, "image size %ux%u: each side must be 1..%u", width, height,
                            LK__MAX_RENDER_SIZE);
    lk_renderer *renderer = calloc(1, sizeof *renderer);
    if (!renderer) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for the renderer");
    renderer->display = EGL_NO_DISPLAY;
    renderer->context = EGL_NO_CONTEXT;
    renderer->width = width;
    renderer->height = height;

    const char *client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
        free(renderer);
        return lk_error_set(
            error, LK_ERR_UNSUPPORTED,
            "EGL has no surfaceless platform (EGL_MESA_platform_surfaceless missing): " LK__GL_PACKAGES);
    }
    EGLDisplay display = eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (display == EGL_NO_DISPLAY) {
        free(renderer);
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "eglGetPlatformDisplay(surfaceless) failed (%s): " LK__GL_PACKAGES,
                            egl_error_name(eglGetError()));
    }
    pthread_mutex_lock(&display_mutex);
    EGLint major = 0, minor = 0;
    EGLBoolean initialized = eglInitialize(display, &major, &minor);
    if (initialized) {
        display_users++;
        dl_iterate_phdr(keep_driver_loaded, NULL);
    }
    pthread_mutex_unlock(&display_mutex);
    if (!initialized) {
        free(renderer);
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "eglInitialize failed (%s): " LK__GL_PACKAGES,
                            egl_error_name(eglGetError()));
    }
    renderer->display = display;

    lk_status status = LK_OK;
    if (!eglBindAPI(EGL_OPENGL_ES_API)) {
        status = lk_error_set(error, LK_ERR_UNSUPPORTED, "eglBindAPI(OpenGL ES) failed (%s): " LK__GL_PACKAGES,
                              egl_error_name(eglGetError()));
        goto fail;
    }
    /* A pbuffer-capable ES2 config if there is one (never used for a
     * surface: the FBO is the target), else no config at all. */
    static const EGLint config_attributes[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                               EGL_OPENGL_ES2_BIT, EGL_NONE};
    EGLConfig config = EGL_NO_CONFIG_KHR;
    EGLint config_count = 0;
    if (!eglChooseConfig(display, config_attributes, &config, 1, &config_count) || config_count < 1) {
        config = EGL_NO_CONFIG_KHR;
        if (!has_extension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_no_config_context")) {
            status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                                  "eglChooseConfig found no OpenGL ES 2 config: " LK__GL_PACKAGES);
            goto fail;
        }
    }
    static const EGLint context_attributes[] = {EGL_CONTEXT_CLIENT_VERSION, 2, EGL_NONE};
    renderer->context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
    if (renderer->context == EGL_NO_CONTEXT) {
        status = lk_error_set(error, LK_ERR_UNSUPPORTED, "eglCreateContext(OpenGL ES 2) failed (%s): " LK__GL_PACKAGES,
                              egl_error_name(eglGetError()));
        goto fail;
    }
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, renderer->context)) {
        status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                              "eglMakeCurrent without a surface failed (%s; EGL_KHR_surfaceless_context "
                              "needed): " LK__GL_PACKAGES,
                              egl_error_name(eglGetError()));
        goto fail;
    }
    const char *gl_renderer = (const char *)glGetString(GL_RENDERER);
    const char *gl_version = (const char *)glGetString(GL_VERSION);
    snprintf(renderer->description, sizeof renderer->description, "%s, %s", gl_renderer ? gl_renderer : "?",
             gl_version ? gl_version : "?");
    status = create_framebuffer(renderer, error);
    if (status != LK_OK) goto fail;
    *out = renderer;
    return LK_OK;

fail:
    lk_renderer_free(renderer);
    return status;
}

const char *lk_renderer_description(const lk_renderer *renderer) { return renderer ? renderer->description : ""; }

void lk_renderer_size(const lk_renderer *renderer, unsigned *width, unsigned *height)
{
    if (width) *width = renderer ? renderer->width : 0;
    if (height) *height = renderer ? renderer->height : 0;
}

lk_status lk_renderer_read_pixels(const lk_renderer *renderer, unsigned char *rgba, lk_error *error)
{
    if (!renderer || !rgba) return lk_error_set(error, LK_ERR_INVALID, "lk_renderer_read_pixels: NULL argument");
    lk_status status = make_current(renderer, error);
    if (status != LK_OK) return status;
    glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, (GLsizei)renderer->width, (GLsizei)renderer->height, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    status = lk__gl_check("glReadPixels", error);
    if (status != LK_OK) return status;
    /* GL's rows run bottom-up; images run top-down. Swap rows in place
     * (bytewise, so no scratch row has to be allocated). */
    size_t row_bytes = (size_t)renderer->width * 4;
    for (size_t top = 0, bottom = renderer->height - 1; top < bottom; top++, bottom--) {
        unsigned char *a = rgba + top * row_bytes, *b = rgba + bottom * row_bytes;
        for (size_t i = 0; i < row_bytes; i++) {
            unsigned char t = a[i];
            a[i] = b[i];
            b[i] = t;
        }
    }
    return LK_OK;
}
