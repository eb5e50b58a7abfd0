/* The BTF test OpenXR runtime: OpenGL swapchains (XR_KHR_opengl_enable through
 * XR_MNDX_egl_enable) and the capture written at each xrEndFrame.
 *
 * Every GL call runs in the app's context: XR_KHR_opengl_enable lets the runtime use it during
 * xrCreateSwapchain, xrDestroySwapchain, the image calls and xrEndFrame; the app may leave it
 * unbound on the calling thread, in which case it is made current here and the previous binding
 * restored. GL state this runtime touches (texture binding, pack/unpack state) is restored. */
#include <dlfcn.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "rt.h"

#define GET_SWAPCHAIN(var, handle, func)                       \
    rt_swapchain *var = rt_handle_get((handle), RT_SWAPCHAIN); \
    if (!var) return rt_refuse(XR_ERROR_HANDLE_INVALID, func, "not a live XrSwapchain")

static void *lookup(rt_gl *gl, const char *name) {
    void *p = (void *)gl->get_proc(name);
    /* core EGL 1.0 entry points need not come from eglGetProcAddress: the app's libEGL is
     * loaded in this process */
    if (!p && !strncmp(name, "egl", 3)) p = dlsym(RTLD_DEFAULT, name);
    return p;
}

int rt_gl_load(rt_gl *gl, const XrGraphicsBindingEGLMNDX *b) {
    memset(gl, 0, sizeof *gl);
    gl->get_proc = b->getProcAddress;
    gl->display = b->display;
    gl->context = b->context;
#define LOAD(field, name)                                                                     \
    if (!(*(void **)&gl->field = lookup(gl, name))) {                                         \
        fprintf(stderr, "[BTF test runtime] the binding's getProcAddress has no %s\n", name); \
        return -1;                                                                            \
    }
    LOAD(GetCurrentContext, "eglGetCurrentContext");
    LOAD(GetCurrentDisplay, "eglGetCurrentDisplay");
    LOAD(GetCurrentSurface, "eglGetCurrentSurface");
    LOAD(MakeCurrent, "eglMakeCurrent");
    LOAD(GenTextures, "glGenTextures");
    LOAD(DeleteTextures, "glDeleteTextures");
    LOAD(BindTexture, "glBindTexture");
    LOAD(TexStorage2D, "glTexStorage2D");
    LOAD(TexSubImage2D, "glTexSubImage2D");
    LOAD(GetTexImage, "glGetTexImage");
    LOAD(GetIntegerv, "glGetIntegerv");
    LOAD(PixelStorei, "glPixelStorei");
    LOAD(BindBuffer, "glBindBuffer");
    LOAD(GetError, "glGetError");
#undef LOAD
    *(void **)&gl->FenceSync = lookup(gl, "glFenceSync"); /* optional: strict teardown only */
    *(void **)&gl->ClientWaitSync = lookup(gl, "glClientWaitSync");
    *(void **)&gl->DeleteSync = lookup(gl, "glDeleteSync");
    return 0;
}

int rt_gl_begin(rt_gl *gl) {
    gl->switched = 0;
    if (gl->GetCurrentContext() == gl->context) return 0;
    gl->prev_display = gl->GetCurrentDisplay();
    gl->prev_context = gl->GetCurrentContext();
    gl->prev_draw = gl->GetCurrentSurface(EGL_DRAW);
    gl->prev_read = gl->GetCurrentSurface(EGL_READ);
    if (!gl->MakeCurrent(gl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, gl->context)) {
        fprintf(stderr, "[BTF test runtime] the app's EGL context cannot be made current here "
                        "(is it bound in another thread?)\n");
        return -1;
    }
    gl->switched = 1;
    return 0;
}

void rt_gl_end(rt_gl *gl) {
    if (!gl->switched) return;
    if (gl->prev_context != EGL_NO_CONTEXT)
        gl->MakeCurrent(gl->prev_display, gl->prev_draw, gl->prev_read, gl->prev_context);
    else
        gl->MakeCurrent(gl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    gl->switched = 0;
}

static int is_srgb(int64_t format) {
    return format == GL_SRGB8_ALPHA8 || format == GL_SRGB8 || format == GL_SRGB_ALPHA ||
           format == GL_SRGB;
}

/* ---- swapchains ---- */
static XrResult XRAPI_CALL rt_EnumerateSwapchainFormats(XrSession session, uint32_t capacity,
                                                        uint32_t *countOutput, int64_t *formats) {
    RT_LOCKED;
    const char *F = "xrEnumerateSwapchainFormats";
    rt_session *s = rt_handle_get(session, RT_SESSION);
    if (!s) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSession");
    const rt_config *cfg = &s->instance->cfg;
    if (!countOutput) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "count output is NULL");
    *countOutput = cfg->format_count;
    if (!capacity) return XR_SUCCESS;
    if (capacity < (uint32_t)cfg->format_count)
        return rt_refuse(XR_ERROR_SIZE_INSUFFICIENT, F, "capacity %u < %d", capacity,
                         cfg->format_count);
    memcpy(formats, cfg->formats, sizeof(int64_t) * cfg->format_count);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_CreateSwapchain(XrSession session, const XrSwapchainCreateInfo *ci,
                                              XrSwapchain *out) {
    RT_LOCKED;
    const char *F = "xrCreateSwapchain";
    rt_session *s = rt_handle_get(session, RT_SESSION);
    if (!s) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSession");
    RT_CHECK_TYPE(ci, XR_TYPE_SWAPCHAIN_CREATE_INFO, F);
    if (s->lost) return rt_refuse(XR_ERROR_SESSION_LOST, F, "the session is in LOSS_PENDING");
    const rt_config *cfg = &s->instance->cfg;
    int known = 0;
    for (int i = 0; i < cfg->format_count; i++)
        known |= cfg->formats[i] == ci->format;
    if (!known)
        return rt_refuse(XR_ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED, F,
                         "format 0x%llx is not among xrEnumerateSwapchainFormats'",
                         (unsigned long long)ci->format);
    if (ci->createFlags & XR_SWAPCHAIN_CREATE_PROTECTED_CONTENT_BIT)
        return rt_refuse(XR_ERROR_FEATURE_UNSUPPORTED, F, "protected content is not supported");
    if (ci->sampleCount != 1)
        return rt_refuse(XR_ERROR_FEATURE_UNSUPPORTED, F, "sampleCount %u (max 1)",
                         ci->sampleCount);
    if (ci->faceCount != 1)
        return rt_refuse(XR_ERROR_FEATURE_UNSUPPORTED, F, "faceCount %u (only 1)", ci->faceCount);
    if (ci->arraySize != 1)
        return rt_refuse(ci->arraySize ? XR_ERROR_FEATURE_UNSUPPORTED : XR_ERROR_VALIDATION_FAILURE,
                         F, "arraySize %u (this runtime makes 2D textures only)", ci->arraySize);
    if (!ci->width || !ci->height || ci->width > (uint32_t)(4 * cfg->eye_w) ||
        ci->height > (uint32_t)(4 * cfg->eye_h))
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "size %ux%u outside 1..%dx%d", ci->width,
                         ci->height, 4 * cfg->eye_w, 4 * cfg->eye_h);
    if (!ci->mipCount) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "mipCount 0");
    rt_gl *gl = &s->gl;
    if (rt_gl_begin(gl)) return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F, "no OpenGL context");
    GLint prev = 0;
    while (gl->GetError() != GL_NO_ERROR) {}
    rt_swapchain *sc = calloc(1, sizeof *sc);
    sc->kind = RT_SWAPCHAIN;
    sc->session = s;
    sc->format = ci->format;
    sc->width = ci->width;
    sc->height = ci->height;
    sc->mips = ci->mipCount;
    sc->last_released = -1;
    gl->GetIntegerv(GL_TEXTURE_BINDING_2D, &prev);
    gl->GenTextures(RT_IMAGES_PER_SWAPCHAIN, sc->images);
    for (int i = 0; i < RT_IMAGES_PER_SWAPCHAIN; i++) {
        gl->BindTexture(GL_TEXTURE_2D, sc->images[i]);
        gl->TexStorage2D(GL_TEXTURE_2D, ci->mipCount, (GLenum)ci->format, ci->width, ci->height);
    }
    gl->BindTexture(GL_TEXTURE_2D, prev);
    GLenum err = gl->GetError();
    if (err != GL_NO_ERROR || !sc->images[0]) {
        gl->DeleteTextures(RT_IMAGES_PER_SWAPCHAIN, sc->images);
        rt_gl_end(gl);
        free(sc);
        return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F,
                         "glTexStorage2D(format 0x%llx) failed with GL error 0x%x",
                         (unsigned long long)ci->format, err);
    }
    rt_gl_end(gl);
    rt_handle_add(sc);
    *out = (XrSwapchain)sc;
    return XR_SUCCESS;
}

/* ---- strict teardown (rt.h) ---- */
static void hazard(const rt_session *s, const char *func, const char *what) {
    int fatal = s->instance->cfg.strict_teardown == 1;
    fprintf(stderr, "[BTF test runtime] strict teardown: %s %s; Monado crashes here%s\n", func,
            what, fatal ? ", so does this runtime (script: strict_teardown)" : "");
    fflush(stderr);
    if (fatal) abort();
}

/* 1 when the app's GL commands so far may still be executing: a fence made now is not yet
 * signalled (glClientWaitSync with no timeout and no flush; after glFinish Mesa signals it at
 * once). 0 when done or unknown (no fences, no context). */
static int gl_work_pending(rt_gl *gl) {
    if (!gl->FenceSync || !gl->ClientWaitSync || !gl->DeleteSync || rt_gl_begin(gl)) return 0;
    GLsync fence = gl->FenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    GLenum r = fence ? gl->ClientWaitSync(fence, 0, 0) : GL_ALREADY_SIGNALED;
    if (fence) gl->DeleteSync(fence);
    rt_gl_end(gl);
    return r == GL_TIMEOUT_EXPIRED;
}

void rt_strict_swapchain(rt_swapchain *sc, const char *func) {
    if (!sc->session->instance->cfg.strict_teardown) return;
    if (sc->queued)
        hazard(sc->session, func, "destroys a swapchain with an image acquired and not released");
    if (gl_work_pending(&sc->session->gl))
        hazard(sc->session, func,
               "destroys a swapchain while the app's GL work may still write into its images (no "
               "glFinish since the last draw)");
}

void rt_strict_session(rt_session *s, const char *func) {
    if (!s->instance->cfg.strict_teardown || s->lost) return;
    if (s->frame_begun) hazard(s, func, "destroys a session with a frame begun and not ended");
    if (s->running)
        hazard(s, func,
               "destroys a running session (not ended with xrEndSession: request exit, wait for "
               "STOPPING, end it)");
}

void rt_swapchain_free(rt_swapchain *sc, const char *func) {
    rt_strict_swapchain(sc, func);
    rt_gl *gl = &sc->session->gl;
    if (!rt_gl_begin(gl)) {
        gl->DeleteTextures(RT_IMAGES_PER_SWAPCHAIN, sc->images);
        rt_gl_end(gl);
    }
    rt_handle_remove(sc);
    free(sc);
}

static XrResult XRAPI_CALL rt_DestroySwapchain(XrSwapchain swapchain) {
    RT_LOCKED;
    GET_SWAPCHAIN(sc, swapchain, "xrDestroySwapchain");
    rt_swapchain_free(sc, "xrDestroySwapchain");
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_EnumerateSwapchainImages(XrSwapchain swapchain, uint32_t capacity,
                                                       uint32_t *countOutput,
                                                       XrSwapchainImageBaseHeader *images) {
    RT_LOCKED;
    const char *F = "xrEnumerateSwapchainImages";
    GET_SWAPCHAIN(sc, swapchain, F);
    if (!countOutput) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "count output is NULL");
    *countOutput = RT_IMAGES_PER_SWAPCHAIN;
    if (!capacity) return XR_SUCCESS;
    if (capacity < RT_IMAGES_PER_SWAPCHAIN)
        return rt_refuse(XR_ERROR_SIZE_INSUFFICIENT, F, "capacity %u < %d", capacity,
                         RT_IMAGES_PER_SWAPCHAIN);
    XrSwapchainImageOpenGLKHR *gl_images = (XrSwapchainImageOpenGLKHR *)images;
    for (int i = 0; i < RT_IMAGES_PER_SWAPCHAIN; i++) {
        if (gl_images[i].type != XR_TYPE_SWAPCHAIN_IMAGE_OPENGL_KHR)
            return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F,
                             "images[%d].type is not XR_TYPE_SWAPCHAIN_IMAGE_OPENGL_KHR", i);
        gl_images[i].image = sc->images[i];
    }
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_AcquireSwapchainImage(XrSwapchain swapchain,
                                                    const XrSwapchainImageAcquireInfo *info,
                                                    uint32_t *index) {
    RT_LOCKED;
    const char *F = "xrAcquireSwapchainImage";
    GET_SWAPCHAIN(sc, swapchain, F);
    if (info && info->type != XR_TYPE_SWAPCHAIN_IMAGE_ACQUIRE_INFO)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "acquireInfo type is wrong");
    if (!index) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "index is NULL");
    if (sc->session->lost)
        return rt_refuse(XR_ERROR_SESSION_LOST, F, "the session is in LOSS_PENDING");
    if (sc->queued == RT_IMAGES_PER_SWAPCHAIN)
        return rt_refuse(XR_ERROR_CALL_ORDER_INVALID, F,
                         "all %d images are acquired and not released", RT_IMAGES_PER_SWAPCHAIN);
    int i = sc->next_acquire;
    sc->next_acquire = (i + 1) % RT_IMAGES_PER_SWAPCHAIN;
    sc->queue[sc->queued++] = i;
    *index = (uint32_t)i;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_WaitSwapchainImage(XrSwapchain swapchain,
                                                 const XrSwapchainImageWaitInfo *info) {
    RT_LOCKED;
    const char *F = "xrWaitSwapchainImage";
    GET_SWAPCHAIN(sc, swapchain, F);
    RT_CHECK_TYPE(info, XR_TYPE_SWAPCHAIN_IMAGE_WAIT_INFO, F);
    if (sc->session->lost)
        return rt_refuse(XR_ERROR_SESSION_LOST, F, "the session is in LOSS_PENDING");
    if (!sc->queued) return rt_refuse(XR_ERROR_CALL_ORDER_INVALID, F, "no image is acquired");
    if (sc->head_waited)
        return rt_refuse(XR_ERROR_CALL_ORDER_INVALID, F,
                         "the oldest acquired image was already waited and not released");
    sc->head_waited = 1;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_ReleaseSwapchainImage(XrSwapchain swapchain,
                                                    const XrSwapchainImageReleaseInfo *info) {
    RT_LOCKED;
    const char *F = "xrReleaseSwapchainImage";
    GET_SWAPCHAIN(sc, swapchain, F);
    if (info && info->type != XR_TYPE_SWAPCHAIN_IMAGE_RELEASE_INFO)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "releaseInfo type is wrong");
    if (sc->session->lost)
        return rt_refuse(XR_ERROR_SESSION_LOST, F, "the session is in LOSS_PENDING");
    if (!sc->queued || !sc->head_waited)
        return rt_refuse(XR_ERROR_CALL_ORDER_INVALID, F,
                         "no image was waited (xrWaitSwapchainImage) before release");
    sc->last_released = sc->queue[0];
    memmove(sc->queue, sc->queue + 1, sizeof(int) * (RT_IMAGES_PER_SWAPCHAIN - 1));
    sc->queued--;
    sc->head_waited = 0;
    return XR_SUCCESS;
}

/* ---- readback ---- */
typedef struct {
    GLint tex, pack_buffer, unpack_buffer, align, row, skip_rows, skip_pixels;
} saved_state;

static void save_state(rt_gl *gl, saved_state *st) {
    gl->GetIntegerv(GL_TEXTURE_BINDING_2D, &st->tex);
    gl->GetIntegerv(GL_PIXEL_PACK_BUFFER_BINDING, &st->pack_buffer);
    gl->GetIntegerv(GL_PIXEL_UNPACK_BUFFER_BINDING, &st->unpack_buffer);
    gl->GetIntegerv(GL_PACK_ALIGNMENT, &st->align);
    gl->GetIntegerv(GL_PACK_ROW_LENGTH, &st->row);
    gl->GetIntegerv(GL_PACK_SKIP_ROWS, &st->skip_rows);
    gl->GetIntegerv(GL_PACK_SKIP_PIXELS, &st->skip_pixels);
    gl->BindBuffer(GL_PIXEL_PACK_BUFFER, 0);
    gl->BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    gl->PixelStorei(GL_PACK_ALIGNMENT, 4);
    gl->PixelStorei(GL_PACK_ROW_LENGTH, 0);
    gl->PixelStorei(GL_PACK_SKIP_ROWS, 0);
    gl->PixelStorei(GL_PACK_SKIP_PIXELS, 0);
}

static void restore_state(rt_gl *gl, const saved_state *st) {
    gl->BindTexture(GL_TEXTURE_2D, st->tex);
    gl->BindBuffer(GL_PIXEL_PACK_BUFFER, st->pack_buffer);
    gl->BindBuffer(GL_PIXEL_UNPACK_BUFFER, st->unpack_buffer);
    gl->PixelStorei(GL_PACK_ALIGNMENT, st->align);
    gl->PixelStorei(GL_PACK_ROW_LENGTH, st->row);
    gl->PixelStorei(GL_PACK_SKIP_ROWS, st->skip_rows);
    gl->PixelStorei(GL_PACK_SKIP_PIXELS, st->skip_pixels);
}

/* Does glGetTexImage(GL_FLOAT) return an sRGB texture's stored (encoded) values or decode them?
 * The GL specification leaves no conversion on image queries; drivers are checked, not trusted:
 * a 1x1 SRGB8_ALPHA8 texel of byte 128 reads 128/255 = 0.502 encoded, 0.216 decoded. */
static int probe_srgb_readback(rt_gl *gl) {
    GLuint tex = 0;
    GLint unpack_align = 4;
    const unsigned char texel[4] = {128, 128, 128, 255};
    float out[4] = {-1, -1, -1, -1};
    gl->GetIntegerv(GL_UNPACK_ALIGNMENT, &unpack_align);
    gl->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl->GenTextures(1, &tex);
    gl->BindTexture(GL_TEXTURE_2D, tex);
    gl->TexStorage2D(GL_TEXTURE_2D, 1, GL_SRGB8_ALPHA8, 1, 1);
    gl->TexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, texel);
    gl->GetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, out);
    gl->DeleteTextures(1, &tex);
    gl->PixelStorei(GL_UNPACK_ALIGNMENT, unpack_align);
    if (fabsf(out[0] - 128.0f / 255.0f) < 0.01f) return 1;
    if (fabsf(out[0] - 0.2158605f) < 0.01f) return 2;
    fprintf(stderr, "[BTF test runtime] sRGB readback probe read %g (neither 0.502 nor 0.216)\n",
            out[0]);
    return 1;
}

static int mkdirs(const char *path) {
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1; *p; p++)
        if (*p == '/') {
            *p = 0;
            if (mkdir(buf, 0777) && errno != EEXIST) return -1;
            *p = '/';
        }
    return mkdir(buf, 0777) && errno != EEXIST ? -1 : 0;
}

static const char *space_name(const rt_space *sp) {
    switch (sp->type) {
    case XR_REFERENCE_SPACE_TYPE_VIEW: return "VIEW";
    case XR_REFERENCE_SPACE_TYPE_LOCAL: return "LOCAL";
    case XR_REFERENCE_SPACE_TYPE_STAGE: return "STAGE";
    default: return "ACTION";
    }
}

static void write_pose(FILE *f, const XrPosef *p) {
    fprintf(f, "[%.9g, %.9g, %.9g, %.9g, %.9g, %.9g, %.9g]", p->position.x, p->position.y,
            p->position.z, p->orientation.x, p->orientation.y, p->orientation.z, p->orientation.w);
}

static void write_fov(FILE *f, const XrFovf *v) {
    fprintf(f, "[%.9g, %.9g, %.9g, %.9g]", v->angleLeft, v->angleRight, v->angleUp, v->angleDown);
}

static int pose_ok(const XrPosef *p) {
    const XrQuaternionf *q = &p->orientation;
    float n = q->x * q->x + q->y * q->y + q->z * q->z + q->w * q->w;
    return fabsf(n - 1.0f) < 1e-3f; /* unit quaternions, with float rounding allowed */
}

/* a sub-image must name a live swapchain of this session that has a released image, and lie
 * inside it */
static XrResult check_sub_image(rt_session *s, const XrSwapchainSubImage *sub, const char *what) {
    const char *F = "xrEndFrame";
    rt_swapchain *sc = rt_handle_get(sub->swapchain, RT_SWAPCHAIN);
    if (!sc || sc->session != s)
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F,
                         "%s.swapchain is not a live XrSwapchain of this session", what);
    if (sc->last_released < 0)
        return rt_refuse(XR_ERROR_LAYER_INVALID, F, "%s's swapchain has no released image", what);
    const XrRect2Di *r = &sub->imageRect;
    if (r->offset.x < 0 || r->offset.y < 0 || r->extent.width <= 0 || r->extent.height <= 0 ||
        (uint32_t)(r->offset.x + r->extent.width) > sc->width ||
        (uint32_t)(r->offset.y + r->extent.height) > sc->height)
        return rt_refuse(XR_ERROR_SWAPCHAIN_RECT_INVALID, F,
                         "%s.imageRect (%d, %d, %d, %d) is outside the %ux%u swapchain", what,
                         r->offset.x, r->offset.y, r->extent.width, r->extent.height, sc->width,
                         sc->height);
    if (sub->imageArrayIndex != 0)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "%s.imageArrayIndex %u >= arraySize 1",
                         what, sub->imageArrayIndex);
    return XR_SUCCESS;
}

XrResult rt_check_quad(rt_session *s, const XrCompositionLayerQuad *quad) {
    rt_space *space = rt_handle_get(quad->space, RT_SPACE);
    if (!space || space->session != s)
        return rt_refuse(XR_ERROR_HANDLE_INVALID, "xrEndFrame",
                         "a quad layer's space is not a live XrSpace of this session");
    if (!pose_ok(&quad->pose))
        return rt_refuse(XR_ERROR_POSE_INVALID, "xrEndFrame",
                         "a quad layer's pose is not a unit quaternion");
    return check_sub_image(s, &quad->subImage, "a quad layer's subImage");
}

XrResult rt_capture_frame(rt_session *s, const XrCompositionLayerProjection *layer, XrTime t) {
    const char *F = "xrEndFrame";
    const rt_config *cfg = &s->instance->cfg;
    rt_space *space = rt_handle_get(layer->space, RT_SPACE);
    if (!space || space->session != s)
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F,
                         "the projection layer's space is not a live XrSpace of this session");
    if (layer->viewCount != (uint32_t)cfg->views)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F,
                         "the projection layer has %u views; the view configuration has %d",
                         layer->viewCount, cfg->views);
    if (!layer->views)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "the projection layer's views is NULL");
    for (int i = 0; i < cfg->views; i++) {
        const XrCompositionLayerProjectionView *v = &layer->views[i];
        if (v->type != XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW)
            return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F,
                             "views[%d].type is not XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW", i);
        if (!pose_ok(&v->pose))
            return rt_refuse(XR_ERROR_POSE_INVALID, F,
                             "views[%d].pose's orientation is not a unit quaternion", i);
        char what[48];
        snprintf(what, sizeof what, "views[%d].subImage", i);
        XrResult r = check_sub_image(s, &v->subImage, what);
        if (XR_FAILED(r)) return r;
    }
    if (!t || !cfg->capture_dir[0]) return XR_SUCCESS;

    char path[4400], tmp[4400];
    if (mkdirs(cfg->capture_dir))
        return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F, "cannot make capture_dir %s",
                         cfg->capture_dir);
    long n = s->submitted;
    rt_gl *gl = &s->gl;
    if (rt_gl_begin(gl))
        return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F, "no OpenGL context for the capture");
    saved_state st;
    save_state(gl, &st);
    XrPosef head, base_world, inv;
    rt_head_pose(s, t, &head);
    rt_space_world_pose(space, t, &base_world);
    rt_pose_inv(&base_world, &inv);
    snprintf(tmp, sizeof tmp, "%s/frame_%05ld.json.tmp", cfg->capture_dir, n);
    FILE *js = fopen(tmp, "w");
    if (!js) {
        restore_state(gl, &st);
        rt_gl_end(gl);
        return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F, "cannot write %s", tmp);
    }
    fprintf(js, "{\"frame\": %ld, \"display_time\": %lld, \"space\": \"%s\", \"head\": ", n,
            (long long)t, space_name(space));
    write_pose(js, &head); /* the script's head pose at display_time, in world (= LOCAL) space */
    fprintf(js, ", \"views\": [");
    for (int i = 0; i < cfg->views; i++) {
        const XrCompositionLayerProjectionView *v = &layer->views[i];
        rt_swapchain *sc = rt_handle_get(v->subImage.swapchain, RT_SWAPCHAIN);
        const XrRect2Di *r = &v->subImage.imageRect;
        const char *encoding = "linear";
        if (is_srgb(sc->format)) {
            if (!gl->srgb_readback) gl->srgb_readback = probe_srgb_readback(gl);
            encoding = gl->srgb_readback == 1 ? "srgb" : "linear";
        }
        float *full = calloc((size_t)4 * sc->width * sc->height, sizeof(float));
        while (gl->GetError() != GL_NO_ERROR) { /* errors of the app's own calls: not ours */
        }
        gl->BindTexture(GL_TEXTURE_2D, sc->images[sc->last_released]);
        gl->GetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, full);
        GLenum err = gl->GetError();
        if (err != GL_NO_ERROR) /* e.g. an integer format: the file holds zeros */
            fprintf(stderr,
                    "[BTF test runtime] xrEndFrame: glGetTexImage(format 0x%llx) failed with GL "
                    "error 0x%x; frame %ld view %d is captured as zeros\n",
                    (unsigned long long)sc->format, err, n, i);
        snprintf(path, sizeof path, "%s/frame_%05ld_view_%d.f32", cfg->capture_dir, n, i);
        FILE *img = fopen(path, "wb");
        for (int y = 0; img && y < r->extent.height; y++) /* rows bottom first, as GL stores them */
            fwrite(full + 4 * ((size_t)(r->offset.y + y) * sc->width + r->offset.x),
                   sizeof(float) * 4, r->extent.width, img);
        if (img) fclose(img);
        free(full);
        XrPosef eye, located;
        rt_eye_pose(cfg, &head, i, &eye);
        rt_pose_mul(&inv, &eye, &located);
        XrFovf located_fov = {cfg->fov[i][0], cfg->fov[i][1], cfg->fov[i][2], cfg->fov[i][3]};
        fprintf(js, "%s\n  {\"pose\": ", i ? "," : "");
        write_pose(js, &v->pose);
        fprintf(js, ", \"fov\": ");
        write_fov(js, &v->fov);
        fprintf(js,
                ", \"rect\": [%d, %d, %d, %d], \"format\": %lld, \"encoding\": \"%s\", \"width\": "
                "%u, \"height\": %u, "
                "\"image_index\": %d, \"readback_ok\": %s, \"file\": \"frame_%05ld_view_%d.f32\", "
                "\"located_pose\": ",
                r->offset.x, r->offset.y, r->extent.width, r->extent.height, (long long)sc->format,
                encoding, sc->width, sc->height, sc->last_released,
                err == GL_NO_ERROR ? "true" : "false", n, i);
        write_pose(js, &located);
        fprintf(js, ", \"located_fov\": ");
        write_fov(js, &located_fov);
        fprintf(js, "}");
    }
    fprintf(js, "\n]}\n");
    fclose(js);
    restore_state(gl, &st);
    rt_gl_end(gl);
    snprintf(path, sizeof path, "%s/frame_%05ld.json", cfg->capture_dir, n);
    if (rename(tmp, path)) return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F, "cannot rename %s", tmp);
    return XR_SUCCESS;
}

const rt_entry rt_swapchain_entries[] = {
    {"xrEnumerateSwapchainFormats", (PFN_xrVoidFunction)rt_EnumerateSwapchainFormats, 0},
    {"xrCreateSwapchain", (PFN_xrVoidFunction)rt_CreateSwapchain, 0},
    {"xrDestroySwapchain", (PFN_xrVoidFunction)rt_DestroySwapchain, 0},
    {"xrEnumerateSwapchainImages", (PFN_xrVoidFunction)rt_EnumerateSwapchainImages, 0},
    {"xrAcquireSwapchainImage", (PFN_xrVoidFunction)rt_AcquireSwapchainImage, 0},
    {"xrWaitSwapchainImage", (PFN_xrVoidFunction)rt_WaitSwapchainImage, 0},
    {"xrReleaseSwapchainImage", (PFN_xrVoidFunction)rt_ReleaseSwapchainImage, 0},
    {NULL, NULL, 0},
};
