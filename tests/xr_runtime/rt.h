/* The BTF test OpenXR runtime: shared declarations.
 *
 * A test double at a hardware boundary: a small OpenXR 1.0 runtime that the REAL OpenXR loader
 * loads through XR_RUNTIME_JSON. It follows the OpenXR specification (not any client's code) for
 * the subset a GL application needs; see docs/development.md "The OpenXR test runtime".
 * One recursive lock serialises every entry point (apps may call xrWaitFrame from another thread).
 */
#ifndef BTF_TEST_RUNTIME_RT_H
#define BTF_TEST_RUNTIME_RT_H

#include <stdint.h>
#include <stdio.h>

#include <EGL/egl.h>
#include <GL/gl.h>

#define XR_USE_PLATFORM_EGL
#define XR_USE_GRAPHICS_API_OPENGL
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>

#define RT_EXPORT __attribute__((visibility("default")))
#define RT_API_VERSION XR_MAKE_VERSION(1, 0, 20) /* the headers this runtime is built against */
#define RT_RUNTIME_NAME "BTF test runtime"
#define RT_SYSTEM_ID ((XrSystemId)0x42)
#define RT_MAX_VIEWS 8
#define RT_MAX_FORMATS 16
#define RT_MAX_EXTENSIONS 16
#define RT_IMAGES_PER_SWAPCHAIN 3
#define RT_MAX_LAYERS 16
#define RT_EVENT_QUEUE 64

/* ---- the control script (BTF_XR_TEST_SCRIPT) ---- */
typedef struct rt_config {
    int views;                  /* view count of the PRIMARY_STEREO configuration (2 normally) */
    int eye_w, eye_h;           /* recommended image size; max = 4x */
    double ipd;                 /* metres */
    float fov[RT_MAX_VIEWS][4]; /* angleLeft, angleRight, angleUp, angleDown (radians) */
    double period_s;            /* predicted display period */
    int head_count;
    double (*head)[7]; /* per submitted frame: x, y, z, qx, qy, qz, qw (last one held) */
    int format_count;
    int64_t formats[RT_MAX_FORMATS];
    int extension_count;
    char extensions[RT_MAX_EXTENSIONS][XR_MAX_EXTENSION_NAME_SIZE];
    int system_available;
    long lose_after_frames;  /* -1: never */
    int render_from_visible; /* shouldRender only from VISIBLE (Monado); default: SYNCHRONIZED */
    int pace;                /* xrWaitFrame sleeps until its frame's slot (real time) */
    double head_motion[2];   /* a sway on the head path: metres, radians (Monado's tracking) */
    int strict_teardown;     /* 1: abort on what crashed Monado at teardown (rt_strict_*);
                              * 2 ("log"): log it and go on (to count how often) */
    char capture_dir[4096];  /* "" = no capture */
} rt_config;

/* Loads the script named by BTF_XR_TEST_SCRIPT (defaults when unset), then the environment's
 * BTF_XR_TEST_PACE_HZ (a positive rate: pace on at that display rate, over the script's). 0 on
 * success; on a bad script or rate logs why to stderr and returns -1. */
int rt_config_load(rt_config *cfg);
void rt_config_load_defaults(rt_config *cfg);
void rt_config_free(rt_config *cfg);

/* ---- objects and handles ---- */
typedef enum rt_kind {
    RT_INSTANCE = 1,
    RT_SESSION,
    RT_SPACE,
    RT_SWAPCHAIN,
    RT_ACTION_SET,
    RT_ACTION
} rt_kind;

typedef struct rt_instance rt_instance;
typedef struct rt_session rt_session;

typedef struct rt_instance {
    rt_kind kind;
    rt_config cfg;
    int ext_opengl, ext_egl;
    int graphics_requirements_called;
    rt_session *session;
    /* paths: index + 1 is the XrPath */
    int path_count, path_cap;
    char **paths;
    /* event queue (ring) */
    XrEventDataBuffer events[RT_EVENT_QUEUE];
    int event_head, event_count;
} rt_instance;

typedef struct rt_gl {
    PFNEGLGETPROCADDRESSPROC get_proc;
    EGLDisplay display;
    EGLContext context;
    /* EGL entry points to bind the app's context when it is not current (GL binding rules
     * allow the app to leave it unbound on the calling thread) */
    EGLContext (*GetCurrentContext)(void);
    EGLDisplay (*GetCurrentDisplay)(void);
    EGLSurface (*GetCurrentSurface)(EGLint);
    EGLBoolean (*MakeCurrent)(EGLDisplay, EGLSurface, EGLSurface, EGLContext);
    void (*GenTextures)(GLsizei, GLuint *);
    void (*DeleteTextures)(GLsizei, const GLuint *);
    void (*BindTexture)(GLenum, GLuint);
    void (*TexStorage2D)(GLenum, GLsizei, GLenum, GLsizei, GLsizei);
    void (*TexSubImage2D)(GLenum, GLint, GLint, GLint, GLsizei, GLsizei, GLenum, GLenum,
                          const void *);
    void (*GetTexImage)(GLenum, GLint, GLenum, GLenum, void *);
    void (*GetIntegerv)(GLenum, GLint *);
    void (*PixelStorei)(GLenum, GLint);
    void (*BindBuffer)(GLenum, GLuint);
    GLenum (*GetError)(void);
    /* fences (GL 3.2; optional): is the app's GL work done? (strict teardown) */
    GLsync (*FenceSync)(GLenum, GLbitfield);
    GLenum (*ClientWaitSync)(GLsync, GLbitfield, GLuint64);
    void (*DeleteSync)(GLsync);
    int srgb_readback; /* 0 unknown, 1 glGetTexImage returns encoded values, 2 it decodes */
    /* saved state of a guard */
    int switched;
    EGLDisplay prev_display;
    EGLContext prev_context;
    EGLSurface prev_draw, prev_read;
} rt_gl;

typedef struct rt_session {
    rt_kind kind;
    rt_instance *instance;
    rt_gl gl;
    XrSessionState state;
    int running, exit_requested, lost;
    int64_t t0;         /* XrTime of xrBeginSession */
    long waited;        /* xrWaitFrame calls since xrBeginSession */
    long waits_unbegun; /* waits not yet consumed by xrBeginFrame */
    int frame_begun;
    long submitted; /* successful xrEndFrame calls */
} rt_session;

typedef struct rt_space {
    rt_kind kind;
    rt_session *session;
    XrReferenceSpaceType type; /* 0 for an action space (never located) */
    XrPosef pose;              /* poseInReferenceSpace */
} rt_space;

typedef struct rt_swapchain {
    rt_kind kind;
    rt_session *session;
    int64_t format;
    uint32_t width, height, mips;
    GLuint images[RT_IMAGES_PER_SWAPCHAIN];
    int queue[RT_IMAGES_PER_SWAPCHAIN]; /* acquired, not yet released, oldest first */
    int queued, head_waited, next_acquire;
    int last_released; /* -1 before the first release */
} rt_swapchain;

typedef struct rt_simple {
    rt_kind kind;
    void *owner;
} rt_simple;

/* handle registry: a handle is valid only while registered with the expected kind */
void *rt_handle_get(const void *handle, rt_kind kind);
void rt_handle_add(void *obj);
void rt_handle_remove(void *obj);
/* the first live object of a kind whose owner (the field after kind) is owner, or NULL */
rt_simple *rt_handle_find_child(rt_kind kind, const void *owner);
void rt_action_set_free(rt_simple *set);

/* logging: every refused call says why on stderr */
XrResult rt_refuse(XrResult result, const char *func, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
const char *rt_result_name(XrResult r);
int64_t rt_now_ns(void);

/* sessions and events */
void rt_set_state(rt_session *s, XrSessionState state);
void rt_session_free(rt_session *s, const char *func); /* func: the destroying call */
XrResult rt_head_pose(rt_session *s, XrTime t, XrPosef *out);
void rt_eye_pose(const rt_config *cfg, const XrPosef *head, int view, XrPosef *out);
XrResult rt_space_world_pose(rt_space *sp, XrTime t, XrPosef *out);
void rt_pose_mul(const XrPosef *a, const XrPosef *b, XrPosef *out);
void rt_pose_inv(const XrPosef *a, XrPosef *out);

/* strict teardown (script "strict_teardown", rt_swapchain.c): what Monado crashed on when an
 * app tore down mid-frame. Each logs the hazard and aborts the process, as Monado crashed (with
 * "log": logs it only):
 * destroying a swapchain with an image acquired and not released, or while the app's GL work
 * may still write into its images (no glFinish: a fence made now is not yet signalled);
 * destroying a session with a frame begun and not ended, or still running (not ended with
 * xrEndSession) unless it was lost. func: the call that destroys. */
void rt_strict_swapchain(rt_swapchain *sc, const char *func);
void rt_strict_session(rt_session *s, const char *func);

/* GL (rt_swapchain.c) */
int rt_gl_load(rt_gl *gl, const XrGraphicsBindingEGLMNDX *binding);
int rt_gl_begin(rt_gl *gl);
void rt_gl_end(rt_gl *gl);
void rt_swapchain_free(rt_swapchain *sc, const char *func); /* func: the destroying call */
XrResult rt_check_quad(rt_session *s, const XrCompositionLayerQuad *quad);
/* display_time 0: validate the layer only; else also read back and write the capture */
XrResult rt_capture_frame(rt_session *s, const XrCompositionLayerProjection *layer,
                          XrTime display_time);

/* the dispatch: name -> function (one table per source file) */
typedef struct rt_entry {
    const char *name;
    PFN_xrVoidFunction fn;
    int needs;
} rt_entry;
enum { RT_NEEDS_NONE = 0, RT_NEEDS_OPENGL = 1, RT_NEEDS_EGL = 2 };
extern const rt_entry rt_session_entries[];
extern const rt_entry rt_swapchain_entries[];
extern const rt_entry rt_action_entries[];

/* RT_LOCKED; as an entry point's first statement holds the runtime's lock until it returns */
int rt_lock_acquire(void);
void rt_lock_release(int *unused);
#define RT_LOCKED                                                                     \
    __attribute__((cleanup(rt_lock_release))) int rt_lock_guard_ = rt_lock_acquire(); \
    (void)rt_lock_guard_

#define RT_CHECK_TYPE(ptr, expected, func)                                                     \
    do {                                                                                       \
        if ((ptr) == NULL)                                                                     \
            return rt_refuse(XR_ERROR_VALIDATION_FAILURE, func, "a required pointer is NULL"); \
        if ((ptr)->type != (expected))                                                         \
            return rt_refuse(XR_ERROR_VALIDATION_FAILURE, func,                                \
                             "structure type %d is not " #expected, (int)(ptr)->type);         \
    } while (0)

#endif
