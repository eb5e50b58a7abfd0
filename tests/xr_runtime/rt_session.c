/* The BTF test OpenXR runtime: sessions (state machine and events), reference spaces, the frame
 * loop and per-eye views from the script's head path. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "rt.h"

#define GET_SESSION(var, handle, func)                     \
    rt_session *var = rt_handle_get((handle), RT_SESSION); \
    if (!var) return rt_refuse(XR_ERROR_HANDLE_INVALID, func, "not a live XrSession")

#define CHECK_NOT_LOST(s, func)                                                              \
    do {                                                                                     \
        if ((s)->lost)                                                                       \
            return rt_refuse(XR_ERROR_SESSION_LOST, func, "the session is in LOSS_PENDING"); \
    } while (0)

/* ---- poses (OpenXR: right-handed, quaternions x, y, z, w) ---- */
static XrQuaternionf qmul(XrQuaternionf a, XrQuaternionf b) {
    return (XrQuaternionf){a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
                           a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
                           a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
                           a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}

static XrVector3f qrot(XrQuaternionf q, XrVector3f v) {
    XrQuaternionf p = {v.x, v.y, v.z, 0};
    XrQuaternionf c = {-q.x, -q.y, -q.z, q.w};
    XrQuaternionf r = qmul(qmul(q, p), c);
    return (XrVector3f){r.x, r.y, r.z};
}

/* out = a * b: b expressed in a's frame, then a into its parent */
void rt_pose_mul(const XrPosef *a, const XrPosef *b, XrPosef *out) {
    XrVector3f t = qrot(a->orientation, b->position);
    XrPosef r = {qmul(a->orientation, b->orientation),
                 {a->position.x + t.x, a->position.y + t.y, a->position.z + t.z}};
    *out = r;
}

void rt_pose_inv(const XrPosef *a, XrPosef *out) {
    XrQuaternionf c = {-a->orientation.x, -a->orientation.y, -a->orientation.z, a->orientation.w};
    XrVector3f t = qrot(c, a->position);
    XrPosef r = {c, {-t.x, -t.y, -t.z}};
    *out = r;
}

static const XrPosef IDENTITY = {{0, 0, 0, 1}, {0, 0, 0}};

/* The frame index whose predicted display time is nearest t; the head path is indexed by it
 * (frame k is predicted at t0 + (k + 1) * period). */
static long frame_at(rt_session *s, XrTime t) {
    int64_t period = (int64_t)(s->instance->cfg.period_s * 1e9);
    double k = (double)(t - s->t0) / (double)period - 1.0;
    return k < 0 ? 0 : (long)llround(k);
}

/* The script's head at frame k, swayed by head_motion (metres, radians; Monado's tracked head
 * is never still): a small position offset and a turn about the head's own y axis, different
 * every frame, the same for the same frame. */
XrResult rt_head_pose(rt_session *s, XrTime t, XrPosef *out) {
    const rt_config *cfg = &s->instance->cfg;
    long k = frame_at(s, t);
    const double *h = cfg->head[k < cfg->head_count ? k : cfg->head_count - 1];
    XrPosef p = {{(float)h[3], (float)h[4], (float)h[5], (float)h[6]},
                 {(float)h[0], (float)h[1], (float)h[2]}};
    double m = cfg->head_motion[0], r = cfg->head_motion[1];
    if (m > 0 || r > 0) {
        double f = (double)k;
        double half = 0.5 * r * sin(1.1 * f + 0.3);
        XrPosef sway = {{0, (float)sin(half), 0, (float)cos(half)},
                        {(float)(m * sin(0.9 * f)), (float)(0.5 * m * sin(1.7 * f + 1.0)),
                         (float)(0.5 * m * cos(1.3 * f))}};
        rt_pose_mul(&p, &sway, &p);
    }
    *out = p;
    return XR_SUCCESS;
}

/* eye i = head moved by -ipd/2 (left, even views) or +ipd/2 (right, odd views) along the head's
 * x axis; one view sits at the head itself */
void rt_eye_pose(const rt_config *cfg, const XrPosef *head, int view, XrPosef *out) {
    float dx = cfg->views == 1 ? 0.0f : (float)(view % 2 ? cfg->ipd / 2 : -cfg->ipd / 2);
    XrPosef offset = {{0, 0, 0, 1}, {dx, 0, 0}};
    rt_pose_mul(head, &offset, out);
}

/* the space's pose in the world (LOCAL == STAGE == world origin; VIEW follows the head) */
XrResult rt_space_world_pose(rt_space *sp, XrTime t, XrPosef *out) {
    XrPosef origin = IDENTITY;
    if (sp->type == XR_REFERENCE_SPACE_TYPE_VIEW) rt_head_pose(sp->session, t, &origin);
    rt_pose_mul(&origin, &sp->pose, out);
    return XR_SUCCESS;
}

/* ---- state machine and events ---- */
void rt_set_state(rt_session *s, XrSessionState state) {
    rt_instance *inst = s->instance;
    s->state = state;
    if (inst->event_count == RT_EVENT_QUEUE) {
        /* full (an app that never polls): drop the oldest */
        inst->event_head = (inst->event_head + 1) % RT_EVENT_QUEUE;
        inst->event_count--;
    }
    XrEventDataBuffer *b = &inst->events[(inst->event_head + inst->event_count++) % RT_EVENT_QUEUE];
    memset(b, 0, sizeof *b);
    XrEventDataSessionStateChanged *e = (XrEventDataSessionStateChanged *)b;
    e->type = XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED;
    e->session = (XrSession)s;
    e->state = state;
    e->time = rt_now_ns();
}

static XrResult XRAPI_CALL rt_CreateSession(XrInstance instance, const XrSessionCreateInfo *info,
                                            XrSession *out) {
    RT_LOCKED;
    const char *F = "xrCreateSession";
    rt_instance *inst = rt_handle_get(instance, RT_INSTANCE);
    if (!inst) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrInstance");
    RT_CHECK_TYPE(info, XR_TYPE_SESSION_CREATE_INFO, F);
    if (info->systemId != RT_SYSTEM_ID || !inst->cfg.system_available)
        return rt_refuse(XR_ERROR_SYSTEM_INVALID, F, "systemId was not returned by xrGetSystem");
    const XrGraphicsBindingEGLMNDX *binding = NULL;
    for (const XrBaseInStructure *n = info->next; n; n = n->next)
        if (n->type == XR_TYPE_GRAPHICS_BINDING_EGL_MNDX)
            binding = (const XrGraphicsBindingEGLMNDX *)n;
    if (!binding || !inst->ext_egl || !inst->ext_opengl)
        return rt_refuse(XR_ERROR_GRAPHICS_DEVICE_INVALID, F,
                         "needs an XrGraphicsBindingEGLMNDX in next (XR_KHR_opengl_enable and "
                         "XR_MNDX_egl_enable enabled); this runtime has no other graphics binding");
    if (!inst->graphics_requirements_called)
        return rt_refuse(XR_ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING, F,
                         "xrGetOpenGLGraphicsRequirementsKHR was not called first");
    if (!binding->getProcAddress || !binding->display || !binding->context)
        return rt_refuse(XR_ERROR_GRAPHICS_DEVICE_INVALID, F,
                         "the EGL binding lacks getProcAddress, display or context");
    if (inst->session) return rt_refuse(XR_ERROR_LIMIT_REACHED, F, "one session per instance");
    rt_session *s = calloc(1, sizeof *s);
    s->kind = RT_SESSION;
    s->instance = inst;
    if (rt_gl_load(&s->gl, binding)) {
        free(s);
        return rt_refuse(XR_ERROR_GRAPHICS_DEVICE_INVALID, F,
                         "the binding's getProcAddress lacks GL or EGL functions");
    }
    rt_handle_add(s);
    inst->session = s;
    rt_set_state(s, XR_SESSION_STATE_IDLE);
    rt_set_state(s, XR_SESSION_STATE_READY);
    *out = (XrSession)s;
    return XR_SUCCESS;
}

static void destroy_children(rt_session *s, const char *func);

void rt_session_free(rt_session *s, const char *func) {
    rt_strict_session(s, func);
    destroy_children(s, func);
    s->instance->session = NULL;
    rt_handle_remove(s);
    free(s);
}

static XrResult XRAPI_CALL rt_DestroySession(XrSession session) {
    RT_LOCKED;
    GET_SESSION(s, session, "xrDestroySession");
    rt_session_free(s, "xrDestroySession");
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_BeginSession(XrSession session, const XrSessionBeginInfo *info) {
    RT_LOCKED;
    const char *F = "xrBeginSession";
    GET_SESSION(s, session, F);
    RT_CHECK_TYPE(info, XR_TYPE_SESSION_BEGIN_INFO, F);
    CHECK_NOT_LOST(s, F);
    if (s->running) return rt_refuse(XR_ERROR_SESSION_RUNNING, F, "the session is already running");
    if (s->state != XR_SESSION_STATE_READY)
        return rt_refuse(XR_ERROR_SESSION_NOT_READY, F, "the session is not READY");
    if (info->primaryViewConfigurationType != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)
        return rt_refuse(XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED, F,
                         "primaryViewConfigurationType %d (only PRIMARY_STEREO)",
                         (int)info->primaryViewConfigurationType);
    s->running = 1;
    s->t0 = rt_now_ns();
    s->waited = s->waits_unbegun = 0;
    s->frame_begun = 0;
    rt_set_state(s, XR_SESSION_STATE_SYNCHRONIZED);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_RequestExitSession(XrSession session) {
    RT_LOCKED;
    const char *F = "xrRequestExitSession";
    GET_SESSION(s, session, F);
    CHECK_NOT_LOST(s, F);
    if (!s->running)
        return rt_refuse(XR_ERROR_SESSION_NOT_RUNNING, F, "the session is not running");
    s->exit_requested = 1;
    if (s->state == XR_SESSION_STATE_FOCUSED) rt_set_state(s, XR_SESSION_STATE_VISIBLE);
    if (s->state == XR_SESSION_STATE_VISIBLE) rt_set_state(s, XR_SESSION_STATE_SYNCHRONIZED);
    if (s->state != XR_SESSION_STATE_STOPPING) rt_set_state(s, XR_SESSION_STATE_STOPPING);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_EndSession(XrSession session) {
    RT_LOCKED;
    const char *F = "xrEndSession";
    GET_SESSION(s, session, F);
    CHECK_NOT_LOST(s, F);
    if (!s->running)
        return rt_refuse(XR_ERROR_SESSION_NOT_RUNNING, F, "the session is not running");
    if (s->state != XR_SESSION_STATE_STOPPING)
        return rt_refuse(XR_ERROR_SESSION_NOT_STOPPING, F,
                         "the session is not STOPPING (call xrRequestExitSession)");
    s->running = 0;
    rt_set_state(s, XR_SESSION_STATE_IDLE);
    if (s->exit_requested) rt_set_state(s, XR_SESSION_STATE_EXITING);
    return XR_SUCCESS;
}

/* ---- spaces ---- */
static XrResult XRAPI_CALL rt_EnumerateReferenceSpaces(XrSession session, uint32_t capacity,
                                                       uint32_t *countOutput,
                                                       XrReferenceSpaceType *spaces) {
    RT_LOCKED;
    const char *F = "xrEnumerateReferenceSpaces";
    GET_SESSION(s, session, F);
    static const XrReferenceSpaceType types[] = {
        XR_REFERENCE_SPACE_TYPE_VIEW, XR_REFERENCE_SPACE_TYPE_LOCAL, XR_REFERENCE_SPACE_TYPE_STAGE};
    if (!countOutput) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "count output is NULL");
    *countOutput = 3;
    if (!capacity) return XR_SUCCESS;
    if (capacity < 3) return rt_refuse(XR_ERROR_SIZE_INSUFFICIENT, F, "capacity %u < 3", capacity);
    memcpy(spaces, types, sizeof types);
    return XR_SUCCESS;
}

static int pose_valid(const XrPosef *p) {
    const XrQuaternionf *q = &p->orientation;
    float n = q->x * q->x + q->y * q->y + q->z * q->z + q->w * q->w;
    return fabsf(n - 1.0f) < 1e-3f; /* the spec asks for unit quaternions; allow float rounding */
}

static XrResult XRAPI_CALL rt_CreateReferenceSpace(XrSession session,
                                                   const XrReferenceSpaceCreateInfo *info,
                                                   XrSpace *out) {
    RT_LOCKED;
    const char *F = "xrCreateReferenceSpace";
    GET_SESSION(s, session, F);
    RT_CHECK_TYPE(info, XR_TYPE_REFERENCE_SPACE_CREATE_INFO, F);
    CHECK_NOT_LOST(s, F);
    if (info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_VIEW &&
        info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_LOCAL &&
        info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_STAGE)
        return rt_refuse(XR_ERROR_REFERENCE_SPACE_UNSUPPORTED, F, "reference space type %d",
                         (int)info->referenceSpaceType);
    if (!pose_valid(&info->poseInReferenceSpace))
        return rt_refuse(XR_ERROR_POSE_INVALID, F,
                         "poseInReferenceSpace's orientation is not a unit quaternion");
    rt_space *sp = calloc(1, sizeof *sp);
    sp->kind = RT_SPACE;
    sp->session = s;
    sp->type = info->referenceSpaceType;
    sp->pose = info->poseInReferenceSpace;
    rt_handle_add(sp);
    *out = (XrSpace)sp;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_CreateActionSpace(XrSession session,
                                                const XrActionSpaceCreateInfo *info, XrSpace *out) {
    RT_LOCKED;
    const char *F = "xrCreateActionSpace";
    GET_SESSION(s, session, F);
    RT_CHECK_TYPE(info, XR_TYPE_ACTION_SPACE_CREATE_INFO, F);
    if (!rt_handle_get(info->action, RT_ACTION))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrAction");
    rt_space *sp = calloc(1, sizeof *sp);
    sp->kind = RT_SPACE;
    sp->session = s;
    sp->type = 0; /* no controller is ever tracked */
    sp->pose = info->poseInActionSpace;
    rt_handle_add(sp);
    *out = (XrSpace)sp;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_DestroySpace(XrSpace space) {
    RT_LOCKED;
    rt_space *sp = rt_handle_get(space, RT_SPACE);
    if (!sp) return rt_refuse(XR_ERROR_HANDLE_INVALID, "xrDestroySpace", "not a live XrSpace");
    rt_handle_remove(sp);
    free(sp);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_GetReferenceSpaceBoundsRect(XrSession session,
                                                          XrReferenceSpaceType type,
                                                          XrExtent2Df *bounds) {
    RT_LOCKED;
    const char *F = "xrGetReferenceSpaceBoundsRect";
    GET_SESSION(s, session, F);
    (void)type;
    bounds->width = bounds->height = 0;
    return XR_SPACE_BOUNDS_UNAVAILABLE;
}

static XrResult XRAPI_CALL rt_LocateSpace(XrSpace space, XrSpace baseSpace, XrTime time,
                                          XrSpaceLocation *loc) {
    RT_LOCKED;
    const char *F = "xrLocateSpace";
    rt_space *a = rt_handle_get(space, RT_SPACE), *b = rt_handle_get(baseSpace, RT_SPACE);
    if (!a || !b) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSpace");
    RT_CHECK_TYPE(loc, XR_TYPE_SPACE_LOCATION, F);
    if (time <= 0) return rt_refuse(XR_ERROR_TIME_INVALID, F, "time %lld", (long long)time);
    if (!a->type || !b->type) { /* action spaces: nothing tracked */
        loc->locationFlags = 0;
        loc->pose = IDENTITY;
        return XR_SUCCESS;
    }
    XrPosef wa, wb, inv;
    rt_space_world_pose(a, time, &wa);
    rt_space_world_pose(b, time, &wb);
    rt_pose_inv(&wb, &inv);
    rt_pose_mul(&inv, &wa, &loc->pose);
    loc->locationFlags =
        XR_SPACE_LOCATION_ORIENTATION_VALID_BIT | XR_SPACE_LOCATION_POSITION_VALID_BIT |
        XR_SPACE_LOCATION_ORIENTATION_TRACKED_BIT | XR_SPACE_LOCATION_POSITION_TRACKED_BIT;
    return XR_SUCCESS;
}

/* ---- the frame loop ---- */
static XrResult XRAPI_CALL rt_WaitFrame(XrSession session, const XrFrameWaitInfo *info,
                                        XrFrameState *state) {
    RT_LOCKED;
    const char *F = "xrWaitFrame";
    GET_SESSION(s, session, F);
    if (info && info->type != XR_TYPE_FRAME_WAIT_INFO)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F,
                         "frameWaitInfo type is not XR_TYPE_FRAME_WAIT_INFO");
    RT_CHECK_TYPE(state, XR_TYPE_FRAME_STATE, F);
    CHECK_NOT_LOST(s, F);
    if (!s->running)
        return rt_refuse(XR_ERROR_SESSION_NOT_RUNNING, F, "the session is not running");
    const rt_config *cfg = &s->instance->cfg;
    int64_t period = (int64_t)(cfg->period_s * 1e9);
    long k = s->waited++;
    s->waits_unbegun++;
    if (cfg->pace) { /* block until this frame's slot opens, one period before its display */
        int64_t wait_ns = s->t0 + k * period - rt_now_ns();
        if (wait_ns > 0) { /* other threads may call in meanwhile (the lock is recursive) */
            struct timespec ts = {wait_ns / 1000000000, wait_ns % 1000000000};
            rt_lock_release(NULL);
            nanosleep(&ts, NULL);
            rt_lock_acquire();
            /* another thread may have destroyed the session (or its instance) meanwhile */
            s = rt_handle_get(session, RT_SESSION);
            if (!s) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "destroyed while waiting");
            cfg = &s->instance->cfg;
        }
    }
    state->predictedDisplayTime = s->t0 + (k + 1) * period;
    state->predictedDisplayPeriod = period;
    int visible = s->state == XR_SESSION_STATE_VISIBLE || s->state == XR_SESSION_STATE_FOCUSED;
    state->shouldRender =
        (visible || (!cfg->render_from_visible && s->state == XR_SESSION_STATE_SYNCHRONIZED))
            ? XR_TRUE
            : XR_FALSE;
    /* the compositor shows the app from its first frame on: VISIBLE now, FOCUSED after the
     * first submitted frame */
    if (s->state == XR_SESSION_STATE_SYNCHRONIZED && !s->exit_requested)
        rt_set_state(s, XR_SESSION_STATE_VISIBLE);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_BeginFrame(XrSession session, const XrFrameBeginInfo *info) {
    RT_LOCKED;
    const char *F = "xrBeginFrame";
    GET_SESSION(s, session, F);
    if (info && info->type != XR_TYPE_FRAME_BEGIN_INFO)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F,
                         "frameBeginInfo type is not XR_TYPE_FRAME_BEGIN_INFO");
    CHECK_NOT_LOST(s, F);
    if (!s->running)
        return rt_refuse(XR_ERROR_SESSION_NOT_RUNNING, F, "the session is not running");
    if (!s->waits_unbegun)
        return rt_refuse(XR_ERROR_CALL_ORDER_INVALID, F,
                         "no xrWaitFrame precedes this xrBeginFrame");
    s->waits_unbegun--;
    XrResult r = XR_SUCCESS;
    if (s->frame_begun) {
        fprintf(stderr, "[BTF test runtime] xrBeginFrame -> XR_FRAME_DISCARDED: the previous frame "
                        "was begun but not ended\n");
        r = XR_FRAME_DISCARDED;
    }
    s->frame_begun = 1;
    return r;
}

static XrResult XRAPI_CALL rt_EndFrame(XrSession session, const XrFrameEndInfo *info) {
    RT_LOCKED;
    const char *F = "xrEndFrame";
    GET_SESSION(s, session, F);
    RT_CHECK_TYPE(info, XR_TYPE_FRAME_END_INFO, F);
    CHECK_NOT_LOST(s, F);
    if (!s->running)
        return rt_refuse(XR_ERROR_SESSION_NOT_RUNNING, F, "the session is not running");
    if (!s->frame_begun)
        return rt_refuse(XR_ERROR_CALL_ORDER_INVALID, F,
                         "no xrBeginFrame precedes this xrEndFrame");
    if (info->displayTime <= 0)
        return rt_refuse(XR_ERROR_TIME_INVALID, F, "displayTime %lld",
                         (long long)info->displayTime);
    if (info->environmentBlendMode != XR_ENVIRONMENT_BLEND_MODE_OPAQUE)
        return rt_refuse(XR_ERROR_ENVIRONMENT_BLEND_MODE_UNSUPPORTED, F,
                         "blend mode %d (only OPAQUE)", (int)info->environmentBlendMode);
    if (info->layerCount > RT_MAX_LAYERS)
        return rt_refuse(XR_ERROR_LAYER_LIMIT_EXCEEDED, F, "%u layers > maxLayerCount %d",
                         info->layerCount, RT_MAX_LAYERS);
    if (info->layerCount && !info->layers)
        return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "layers is NULL");
    const XrCompositionLayerProjection *projection = NULL;
    for (uint32_t i = 0; i < info->layerCount; i++) {
        const XrCompositionLayerBaseHeader *l = info->layers[i];
        if (!l) return rt_refuse(XR_ERROR_LAYER_INVALID, F, "layers[%u] is NULL", i);
        if (l->type == XR_TYPE_COMPOSITION_LAYER_QUAD) { /* validated, composited, not captured */
            XrResult r = rt_check_quad(s, (const XrCompositionLayerQuad *)l);
            if (XR_FAILED(r)) return r;
            continue;
        }
        if (l->type != XR_TYPE_COMPOSITION_LAYER_PROJECTION)
            return rt_refuse(
                XR_ERROR_LAYER_INVALID, F,
                "layers[%u] has type %d; this runtime composites projection and quad layers only",
                i, (int)l->type);
        XrResult r =
            rt_capture_frame(s, (const XrCompositionLayerProjection *)l, 0); /* validation only */
        if (XR_FAILED(r)) return r;
        if (!projection) projection = (const XrCompositionLayerProjection *)l;
    }
    s->frame_begun = 0;
    if (projection) {
        XrResult r = rt_capture_frame(s, projection, info->displayTime);
        if (XR_FAILED(r)) return r;
    }
    s->submitted++;
    if (s->state == XR_SESSION_STATE_VISIBLE && !s->exit_requested)
        rt_set_state(s, XR_SESSION_STATE_FOCUSED);
    long lose = s->instance->cfg.lose_after_frames;
    if (lose >= 0 && s->submitted >= lose && !s->lost) {
        fprintf(stderr,
                "[BTF test runtime] the session is lost after %ld frames (script: "
                "lose_session_after_frames)\n",
                s->submitted);
        s->lost = 1;
        rt_set_state(s, XR_SESSION_STATE_LOSS_PENDING);
    }
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_LocateViews(XrSession session, const XrViewLocateInfo *info,
                                          XrViewState *viewState, uint32_t capacity,
                                          uint32_t *countOutput, XrView *views) {
    RT_LOCKED;
    const char *F = "xrLocateViews";
    GET_SESSION(s, session, F);
    RT_CHECK_TYPE(info, XR_TYPE_VIEW_LOCATE_INFO, F);
    RT_CHECK_TYPE(viewState, XR_TYPE_VIEW_STATE, F);
    CHECK_NOT_LOST(s, F);
    if (info->viewConfigurationType != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)
        return rt_refuse(XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED, F, "view configuration %d",
                         (int)info->viewConfigurationType);
    if (info->displayTime <= 0)
        return rt_refuse(XR_ERROR_TIME_INVALID, F, "displayTime %lld",
                         (long long)info->displayTime);
    rt_space *base = rt_handle_get(info->space, RT_SPACE);
    if (!base) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "info->space is not a live XrSpace");
    const rt_config *cfg = &s->instance->cfg;
    if (!countOutput) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "count output is NULL");
    *countOutput = cfg->views;
    if (!capacity) return XR_SUCCESS;
    if (capacity < (uint32_t)cfg->views)
        return rt_refuse(XR_ERROR_SIZE_INSUFFICIENT, F, "capacity %u < %d views", capacity,
                         cfg->views);
    XrPosef head, base_world, inv;
    rt_head_pose(s, info->displayTime, &head);
    if (!base->type) { /* an action space: untracked */
        viewState->viewStateFlags = 0;
        return XR_SUCCESS;
    }
    rt_space_world_pose(base, info->displayTime, &base_world);
    rt_pose_inv(&base_world, &inv);
    for (int i = 0; i < cfg->views; i++) {
        RT_CHECK_TYPE(&views[i], XR_TYPE_VIEW, F);
        XrPosef eye;
        rt_eye_pose(cfg, &head, i, &eye);
        rt_pose_mul(&inv, &eye, &views[i].pose);
        views[i].fov = (XrFovf){cfg->fov[i][0], cfg->fov[i][1], cfg->fov[i][2], cfg->fov[i][3]};
    }
    viewState->viewStateFlags =
        XR_VIEW_STATE_ORIENTATION_VALID_BIT | XR_VIEW_STATE_POSITION_VALID_BIT |
        XR_VIEW_STATE_ORIENTATION_TRACKED_BIT | XR_VIEW_STATE_POSITION_TRACKED_BIT;
    return XR_SUCCESS;
}

static void destroy_children(rt_session *s, const char *func) {
    /* spaces, swapchains and action spaces die with their session (the spec's child handles) */
    rt_simple *child;
    while ((child = rt_handle_find_child(RT_SWAPCHAIN, s)))
        rt_swapchain_free((rt_swapchain *)child, func);
    while ((child = rt_handle_find_child(RT_SPACE, s))) {
        rt_handle_remove(child);
        free(child);
    }
}

const rt_entry rt_session_entries[] = {
    {"xrCreateSession", (PFN_xrVoidFunction)rt_CreateSession, 0},
    {"xrDestroySession", (PFN_xrVoidFunction)rt_DestroySession, 0},
    {"xrBeginSession", (PFN_xrVoidFunction)rt_BeginSession, 0},
    {"xrEndSession", (PFN_xrVoidFunction)rt_EndSession, 0},
    {"xrRequestExitSession", (PFN_xrVoidFunction)rt_RequestExitSession, 0},
    {"xrEnumerateReferenceSpaces", (PFN_xrVoidFunction)rt_EnumerateReferenceSpaces, 0},
    {"xrCreateReferenceSpace", (PFN_xrVoidFunction)rt_CreateReferenceSpace, 0},
    {"xrCreateActionSpace", (PFN_xrVoidFunction)rt_CreateActionSpace, 0},
    {"xrDestroySpace", (PFN_xrVoidFunction)rt_DestroySpace, 0},
    {"xrGetReferenceSpaceBoundsRect", (PFN_xrVoidFunction)rt_GetReferenceSpaceBoundsRect, 0},
    {"xrLocateSpace", (PFN_xrVoidFunction)rt_LocateSpace, 0},
    {"xrWaitFrame", (PFN_xrVoidFunction)rt_WaitFrame, 0},
    {"xrBeginFrame", (PFN_xrVoidFunction)rt_BeginFrame, 0},
    {"xrEndFrame", (PFN_xrVoidFunction)rt_EndFrame, 0},
    {"xrLocateViews", (PFN_xrVoidFunction)rt_LocateViews, 0},
    {NULL, NULL, 0},
};
