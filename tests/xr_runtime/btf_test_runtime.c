/* The BTF test OpenXR runtime: loader negotiation, dispatch, instance, system, view
 * configurations, paths and strings. Sessions and frames: rt_session.c; OpenGL swapchains and the
 * capture: rt_swapchain.c; actions: rt_actions.c; the control script: rt_config.c. */
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <openxr/openxr_reflection.h>

#include "rt.h"

/* ---- the loader/runtime negotiation structs (the OpenXR loader specification; Debian's
 * libopenxr-dev 1.0.20 does not ship openxr_loader_negotiation.h) ---- */
typedef enum XrLoaderInterfaceStructs {
    XR_LOADER_INTERFACE_STRUCT_UNINTIALIZED = 0,
    XR_LOADER_INTERFACE_STRUCT_LOADER_INFO = 1,
    XR_LOADER_INTERFACE_STRUCT_API_LAYER_REQUEST = 2,
    XR_LOADER_INTERFACE_STRUCT_RUNTIME_REQUEST = 3,
    XR_LOADER_INTERFACE_STRUCT_API_LAYER_CREATE_INFO = 4,
    XR_LOADER_INTERFACE_STRUCT_API_LAYER_NEXT_INFO = 5,
    XR_LOADER_INTERFACE_STRUCTS_MAX_ENUM = 0x7FFFFFFF
} XrLoaderInterfaceStructs;

#define XR_LOADER_INFO_STRUCT_VERSION 1
#define XR_RUNTIME_INFO_STRUCT_VERSION 1
#define XR_CURRENT_LOADER_RUNTIME_VERSION 1

typedef struct XrNegotiateLoaderInfo {
    XrLoaderInterfaceStructs structType;
    uint32_t structVersion;
    size_t structSize;
    uint32_t minInterfaceVersion;
    uint32_t maxInterfaceVersion;
    XrVersion minApiVersion;
    XrVersion maxApiVersion;
} XrNegotiateLoaderInfo;

typedef struct XrNegotiateRuntimeRequest {
    XrLoaderInterfaceStructs structType;
    uint32_t structVersion;
    size_t structSize;
    uint32_t runtimeInterfaceVersion;
    XrVersion runtimeApiVersion;
    PFN_xrGetInstanceProcAddr getInstanceProcAddr;
} XrNegotiateRuntimeRequest;

/* ---- the lock, logging, time, handles ---- */
static pthread_mutex_t lock;
static pthread_once_t lock_once = PTHREAD_ONCE_INIT;

static void lock_init(void) {
    pthread_mutexattr_t attr;
    pthread_mutexattr_init(&attr);
    pthread_mutexattr_settype(&attr, PTHREAD_MUTEX_RECURSIVE);
    pthread_mutex_init(&lock, &attr);
}

int rt_lock_acquire(void) {
    pthread_once(&lock_once, lock_init);
    pthread_mutex_lock(&lock);
    return 0;
}

void rt_lock_release(int *unused) {
    (void)unused;
    pthread_mutex_unlock(&lock);
}

/* the case lists come from openxr_reflection.h */
const char *rt_result_name(XrResult r) {
    // clang-format off
    switch (r) {
#define RT_CASE(name, value) case name: return #name;
        XR_LIST_ENUM_XrResult(RT_CASE)
#undef RT_CASE
    default: return "XR_UNKNOWN_RESULT";
    }
    // clang-format on
}

XrResult rt_refuse(XrResult result, const char *func, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "[BTF test runtime] %s -> %s: ", func, rt_result_name(result));
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    return result;
}

int64_t rt_now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* A handle is the object's address; it is valid only while registered. Looking it up in the
 * registry (instead of dereferencing) lets invalid handles give XR_ERROR_HANDLE_INVALID. */
static void **registry;
static int registry_count, registry_cap;

void rt_handle_add(void *obj) {
    if (registry_count == registry_cap) {
        registry_cap = registry_cap ? registry_cap * 2 : 64;
        registry = realloc(registry, sizeof(void *) * registry_cap);
    }
    registry[registry_count++] = obj;
}

void rt_handle_remove(void *obj) {
    for (int i = 0; i < registry_count; i++)
        if (registry[i] == obj) {
            registry[i] = registry[--registry_count];
            return;
        }
}

void *rt_handle_get(const void *handle, rt_kind kind) {
    if (!handle) return NULL;
    for (int i = 0; i < registry_count; i++)
        if (registry[i] == handle) return *(rt_kind *)registry[i] == kind ? registry[i] : NULL;
    return NULL;
}

rt_simple *rt_handle_find_child(rt_kind kind, const void *owner) {
    for (int i = 0; i < registry_count; i++) {
        rt_simple *o = registry[i];
        if (o->kind == kind && o->owner == owner) return o;
    }
    return NULL;
}

#define GET_INSTANCE(var, handle, func)                      \
    rt_instance *var = rt_handle_get((handle), RT_INSTANCE); \
    if (!var) return rt_refuse(XR_ERROR_HANDLE_INVALID, func, "not a live XrInstance")

/* the two-call idiom: capacity 0 asks for the count */
#define TWO_CALL(func, capacity, count_out, count)                                       \
    do {                                                                                 \
        if (!(count_out))                                                                \
            return rt_refuse(XR_ERROR_VALIDATION_FAILURE, func, "count output is NULL"); \
        *(count_out) = (uint32_t)(count);                                                \
        if ((capacity) == 0) return XR_SUCCESS;                                          \
        if ((capacity) < (uint32_t)(count))                                              \
            return rt_refuse(XR_ERROR_SIZE_INSUFFICIENT, func, "capacity %u < %u",       \
                             (unsigned)(capacity), (unsigned)(count));                   \
    } while (0)

static int offered(const rt_config *cfg, const char *name) {
    for (int i = 0; i < cfg->extension_count; i++)
        if (!strcmp(cfg->extensions[i], name)) return 1;
    return 0;
}

static int known_extension(const char *name) {
    return !strcmp(name, XR_KHR_OPENGL_ENABLE_EXTENSION_NAME) ||
           !strcmp(name, XR_MNDX_EGL_ENABLE_EXTENSION_NAME);
}

/* ---- instance ---- */
static XrResult XRAPI_CALL rt_EnumerateInstanceExtensionProperties(const char *layerName,
                                                                   uint32_t capacity,
                                                                   uint32_t *countOutput,
                                                                   XrExtensionProperties *props) {
    RT_LOCKED;
    const char *F = "xrEnumerateInstanceExtensionProperties";
    if (layerName && *layerName)
        return rt_refuse(XR_ERROR_API_LAYER_NOT_PRESENT, F, "this runtime has no layer %s",
                         layerName);
    rt_config cfg;
    if (rt_config_load(&cfg)) {
        /* offer what the runtime implements so that xrCreateInstance is reached and fails
         * with XR_ERROR_RUNTIME_FAILURE (the reason is already on stderr) */
        rt_config_free(&cfg);
        rt_config_load_defaults(&cfg);
    }
    /* only extensions this runtime implements are offered, even if the script lists more */
    int n = 0;
    const char *names[RT_MAX_EXTENSIONS];
    for (int i = 0; i < cfg.extension_count; i++)
        if (known_extension(cfg.extensions[i])) names[n++] = cfg.extensions[i];
    rt_config_free(&cfg);
    TWO_CALL(F, capacity, countOutput, n);
    for (int i = 0; i < n; i++) {
        if (props[i].type != XR_TYPE_EXTENSION_PROPERTIES)
            return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F,
                             "props[%d].type is not XR_TYPE_EXTENSION_PROPERTIES", i);
        strcpy(props[i].extensionName, names[i]);
        props[i].extensionVersion = !strcmp(names[i], XR_KHR_OPENGL_ENABLE_EXTENSION_NAME)
                                        ? XR_KHR_opengl_enable_SPEC_VERSION
                                        : XR_MNDX_egl_enable_SPEC_VERSION;
    }
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_EnumerateApiLayerProperties(uint32_t capacity, uint32_t *countOutput,
                                                          XrApiLayerProperties *props) {
    RT_LOCKED;
    (void)props;
    if (!countOutput) return XR_ERROR_VALIDATION_FAILURE;
    *countOutput = 0; /* no layers: the loader answers this itself anyway */
    (void)capacity;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_CreateInstance(const XrInstanceCreateInfo *info, XrInstance *out) {
    RT_LOCKED;
    const char *F = "xrCreateInstance";
    RT_CHECK_TYPE(info, XR_TYPE_INSTANCE_CREATE_INFO, F);
    if (!out) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "instance output is NULL");
    XrVersion v = info->applicationInfo.apiVersion;
    if (XR_VERSION_MAJOR(v) != 1 || XR_VERSION_MINOR(v) != 0)
        return rt_refuse(XR_ERROR_API_VERSION_UNSUPPORTED, F,
                         "apiVersion %u.%u.%u requested; this runtime implements OpenXR 1.0",
                         XR_VERSION_MAJOR(v), XR_VERSION_MINOR(v), XR_VERSION_PATCH(v));
    if (!info->applicationInfo.applicationName[0])
        return rt_refuse(XR_ERROR_NAME_INVALID, F, "applicationName is empty");
    if (info->enabledApiLayerCount)
        return rt_refuse(XR_ERROR_API_LAYER_NOT_PRESENT, F, "this runtime offers no API layers");
    rt_instance *inst = calloc(1, sizeof *inst);
    inst->kind = RT_INSTANCE;
    if (rt_config_load(&inst->cfg)) {
        rt_config_free(&inst->cfg);
        free(inst);
        return rt_refuse(XR_ERROR_RUNTIME_FAILURE, F, "bad control script (BTF_XR_TEST_SCRIPT)");
    }
    for (uint32_t i = 0; i < info->enabledExtensionCount; i++) {
        const char *name = info->enabledExtensionNames[i];
        if (!known_extension(name) || !offered(&inst->cfg, name)) {
            rt_config_free(&inst->cfg);
            free(inst);
            return rt_refuse(XR_ERROR_EXTENSION_NOT_PRESENT, F,
                             "extension %s is not offered by this runtime", name);
        }
        if (!strcmp(name, XR_KHR_OPENGL_ENABLE_EXTENSION_NAME)) inst->ext_opengl = 1;
        if (!strcmp(name, XR_MNDX_EGL_ENABLE_EXTENSION_NAME)) inst->ext_egl = 1;
    }
    rt_handle_add(inst);
    *out = (XrInstance)inst;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_DestroyInstance(XrInstance instance) {
    RT_LOCKED;
    GET_INSTANCE(inst, instance, "xrDestroyInstance");
    if (inst->session) rt_session_free(inst->session, "xrDestroyInstance");
    rt_simple *set; /* action sets (and their actions) are the instance's children */
    while ((set = rt_handle_find_child(RT_ACTION_SET, inst)))
        rt_action_set_free(set);
    for (int i = 0; i < inst->path_count; i++)
        free(inst->paths[i]);
    free(inst->paths);
    rt_config_free(&inst->cfg);
    rt_handle_remove(inst);
    free(inst);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_GetInstanceProperties(XrInstance instance, XrInstanceProperties *p) {
    RT_LOCKED;
    const char *F = "xrGetInstanceProperties";
    GET_INSTANCE(inst, instance, F);
    RT_CHECK_TYPE(p, XR_TYPE_INSTANCE_PROPERTIES, F);
    p->runtimeVersion = XR_MAKE_VERSION(0, 1, 0);
    snprintf(p->runtimeName, sizeof p->runtimeName, "%s", RT_RUNTIME_NAME);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_ResultToString(XrInstance instance, XrResult value,
                                             char buffer[XR_MAX_RESULT_STRING_SIZE]) {
    RT_LOCKED;
    GET_INSTANCE(inst, instance, "xrResultToString");
    const char *name = rt_result_name(value);
    if (!strcmp(name, "XR_UNKNOWN_RESULT"))
        snprintf(buffer, XR_MAX_RESULT_STRING_SIZE,
                 value >= 0 ? "XR_UNKNOWN_SUCCESS_%d" : "XR_UNKNOWN_FAILURE_%d", (int)value);
    else
        snprintf(buffer, XR_MAX_RESULT_STRING_SIZE, "%s", name);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_StructureTypeToString(XrInstance instance, XrStructureType value,
                                                    char buffer[XR_MAX_STRUCTURE_NAME_SIZE]) {
    RT_LOCKED;
    GET_INSTANCE(inst, instance, "xrStructureTypeToString");
    const char *name = NULL;
    // clang-format off
    switch (value) {
#define RT_CASE(n, v) case n: name = #n; break;
        XR_LIST_ENUM_XrStructureType(RT_CASE)
#undef RT_CASE
    default: break;
    }
    // clang-format on
    if (name)
        snprintf(buffer, XR_MAX_STRUCTURE_NAME_SIZE, "%s", name);
    else
        snprintf(buffer, XR_MAX_STRUCTURE_NAME_SIZE, "XR_UNKNOWN_STRUCTURE_TYPE_%d", (int)value);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_PollEvent(XrInstance instance, XrEventDataBuffer *event) {
    RT_LOCKED;
    const char *F = "xrPollEvent";
    GET_INSTANCE(inst, instance, F);
    RT_CHECK_TYPE(event, XR_TYPE_EVENT_DATA_BUFFER, F);
    if (!inst->event_count) return XR_EVENT_UNAVAILABLE;
    *event = inst->events[inst->event_head];
    inst->event_head = (inst->event_head + 1) % RT_EVENT_QUEUE;
    inst->event_count--;
    return XR_SUCCESS;
}

/* ---- system and view configurations ---- */
#define CHECK_SYSTEM(inst, id, func)                                                               \
    do {                                                                                           \
        if ((id) != RT_SYSTEM_ID || !(inst)->cfg.system_available)                                 \
            return rt_refuse(XR_ERROR_SYSTEM_INVALID, func,                                        \
                             "systemId %llu is not this runtime's HMD", (unsigned long long)(id)); \
    } while (0)

static XrResult XRAPI_CALL rt_GetSystem(XrInstance instance, const XrSystemGetInfo *info,
                                        XrSystemId *id) {
    RT_LOCKED;
    const char *F = "xrGetSystem";
    GET_INSTANCE(inst, instance, F);
    RT_CHECK_TYPE(info, XR_TYPE_SYSTEM_GET_INFO, F);
    if (info->formFactor != XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY &&
        info->formFactor != XR_FORM_FACTOR_HANDHELD_DISPLAY)
        return rt_refuse(XR_ERROR_FORM_FACTOR_UNSUPPORTED, F, "form factor %d is not defined",
                         (int)info->formFactor);
    if (info->formFactor != XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY)
        return rt_refuse(XR_ERROR_FORM_FACTOR_UNSUPPORTED, F,
                         "this runtime has only a head-mounted display");
    if (!inst->cfg.system_available)
        return rt_refuse(
            XR_ERROR_FORM_FACTOR_UNAVAILABLE, F,
            "the head-mounted display is not connected (script: system_available false)");
    *id = RT_SYSTEM_ID;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_GetSystemProperties(XrInstance instance, XrSystemId id,
                                                  XrSystemProperties *p) {
    RT_LOCKED;
    const char *F = "xrGetSystemProperties";
    GET_INSTANCE(inst, instance, F);
    CHECK_SYSTEM(inst, id, F);
    RT_CHECK_TYPE(p, XR_TYPE_SYSTEM_PROPERTIES, F);
    p->systemId = id;
    p->vendorId = 0x42;
    snprintf(p->systemName, sizeof p->systemName, "BTF test HMD (simulated)");
    p->graphicsProperties.maxSwapchainImageWidth = 4 * inst->cfg.eye_w;
    p->graphicsProperties.maxSwapchainImageHeight = 4 * inst->cfg.eye_h;
    p->graphicsProperties.maxLayerCount = RT_MAX_LAYERS;
    p->trackingProperties.orientationTracking = XR_TRUE;
    p->trackingProperties.positionTracking = XR_TRUE;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_EnumerateViewConfigurations(XrInstance instance, XrSystemId id,
                                                          uint32_t capacity, uint32_t *countOutput,
                                                          XrViewConfigurationType *types) {
    RT_LOCKED;
    const char *F = "xrEnumerateViewConfigurations";
    GET_INSTANCE(inst, instance, F);
    CHECK_SYSTEM(inst, id, F);
    TWO_CALL(F, capacity, countOutput, 1);
    types[0] = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
    return XR_SUCCESS;
}

#define CHECK_VIEW_CONFIG(type, func)                                                     \
    do {                                                                                  \
        if ((type) != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)                          \
            return rt_refuse(XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED, func,          \
                             "view configuration %d (only PRIMARY_STEREO)", (int)(type)); \
    } while (0)

static XrResult XRAPI_CALL rt_GetViewConfigurationProperties(XrInstance instance, XrSystemId id,
                                                             XrViewConfigurationType type,
                                                             XrViewConfigurationProperties *p) {
    RT_LOCKED;
    const char *F = "xrGetViewConfigurationProperties";
    GET_INSTANCE(inst, instance, F);
    CHECK_SYSTEM(inst, id, F);
    CHECK_VIEW_CONFIG(type, F);
    RT_CHECK_TYPE(p, XR_TYPE_VIEW_CONFIGURATION_PROPERTIES, F);
    p->viewConfigurationType = type;
    p->fovMutable = XR_TRUE;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_EnumerateViewConfigurationViews(XrInstance instance, XrSystemId id,
                                                              XrViewConfigurationType type,
                                                              uint32_t capacity,
                                                              uint32_t *countOutput,
                                                              XrViewConfigurationView *views) {
    RT_LOCKED;
    const char *F = "xrEnumerateViewConfigurationViews";
    GET_INSTANCE(inst, instance, F);
    CHECK_SYSTEM(inst, id, F);
    CHECK_VIEW_CONFIG(type, F);
    TWO_CALL(F, capacity, countOutput, inst->cfg.views);
    for (int i = 0; i < inst->cfg.views; i++) {
        RT_CHECK_TYPE(&views[i], XR_TYPE_VIEW_CONFIGURATION_VIEW, F);
        views[i].recommendedImageRectWidth = inst->cfg.eye_w;
        views[i].recommendedImageRectHeight = inst->cfg.eye_h;
        views[i].maxImageRectWidth = 4 * inst->cfg.eye_w;
        views[i].maxImageRectHeight = 4 * inst->cfg.eye_h;
        views[i].recommendedSwapchainSampleCount = 1;
        views[i].maxSwapchainSampleCount = 1;
    }
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_EnumerateEnvironmentBlendModes(XrInstance instance, XrSystemId id,
                                                             XrViewConfigurationType type,
                                                             uint32_t capacity,
                                                             uint32_t *countOutput,
                                                             XrEnvironmentBlendMode *modes) {
    RT_LOCKED;
    const char *F = "xrEnumerateEnvironmentBlendModes";
    GET_INSTANCE(inst, instance, F);
    CHECK_SYSTEM(inst, id, F);
    CHECK_VIEW_CONFIG(type, F);
    TWO_CALL(F, capacity, countOutput, 1);
    modes[0] = XR_ENVIRONMENT_BLEND_MODE_OPAQUE;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_GetOpenGLGraphicsRequirementsKHR(
    XrInstance instance, XrSystemId id, XrGraphicsRequirementsOpenGLKHR *req) {
    RT_LOCKED;
    const char *F = "xrGetOpenGLGraphicsRequirementsKHR";
    GET_INSTANCE(inst, instance, F);
    CHECK_SYSTEM(inst, id, F);
    RT_CHECK_TYPE(req, XR_TYPE_GRAPHICS_REQUIREMENTS_OPENGL_KHR, F);
    req->minApiVersionSupported = XR_MAKE_VERSION(3, 3, 0);
    req->maxApiVersionSupported = XR_MAKE_VERSION(4, 6, 0);
    inst->graphics_requirements_called = 1;
    return XR_SUCCESS;
}

/* ---- paths ---- */
static int path_format_ok(const char *s) {
    /* well-formed: starts with '/', no empty or trailing element, [a-z0-9-_.] elements */
    size_t n = strlen(s);
    if (n < 2 || s[0] != '/' || s[n - 1] == '/' || n >= XR_MAX_PATH_LENGTH) return 0;
    for (size_t i = 1; i < n; i++) {
        char c = s[i];
        if (c == '/' && s[i - 1] == '/') return 0;
        if (!(c == '/' || c == '-' || c == '_' || c == '.' || (c >= 'a' && c <= 'z') ||
              (c >= '0' && c <= '9')))
            return 0;
    }
    return 1;
}

static XrResult XRAPI_CALL rt_StringToPath(XrInstance instance, const char *str, XrPath *path) {
    RT_LOCKED;
    const char *F = "xrStringToPath";
    GET_INSTANCE(inst, instance, F);
    if (!str || !path) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "NULL argument");
    if (!path_format_ok(str))
        return rt_refuse(XR_ERROR_PATH_FORMAT_INVALID, F, "%s is not a well-formed path", str);
    for (int i = 0; i < inst->path_count; i++)
        if (!strcmp(inst->paths[i], str)) {
            *path = (XrPath)(i + 1);
            return XR_SUCCESS;
        }
    if (inst->path_count == inst->path_cap) {
        inst->path_cap = inst->path_cap ? 2 * inst->path_cap : 64;
        inst->paths = realloc(inst->paths, sizeof(char *) * inst->path_cap);
    }
    inst->paths[inst->path_count++] = strdup(str);
    *path = (XrPath)inst->path_count;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_PathToString(XrInstance instance, XrPath path, uint32_t capacity,
                                           uint32_t *countOutput, char *buffer) {
    RT_LOCKED;
    const char *F = "xrPathToString";
    GET_INSTANCE(inst, instance, F);
    if (path == XR_NULL_PATH || path > (XrPath)inst->path_count)
        return rt_refuse(XR_ERROR_PATH_INVALID, F, "path %llu was not made by xrStringToPath",
                         (unsigned long long)path);
    const char *s = inst->paths[path - 1];
    TWO_CALL(F, capacity, countOutput, strlen(s) + 1);
    memcpy(buffer, s, strlen(s) + 1);
    return XR_SUCCESS;
}

/* ---- dispatch ---- */
static const rt_entry instance_entries[] = {
    {"xrDestroyInstance", (PFN_xrVoidFunction)rt_DestroyInstance, 0},
    {"xrGetInstanceProperties", (PFN_xrVoidFunction)rt_GetInstanceProperties, 0},
    {"xrResultToString", (PFN_xrVoidFunction)rt_ResultToString, 0},
    {"xrStructureTypeToString", (PFN_xrVoidFunction)rt_StructureTypeToString, 0},
    {"xrPollEvent", (PFN_xrVoidFunction)rt_PollEvent, 0},
    {"xrGetSystem", (PFN_xrVoidFunction)rt_GetSystem, 0},
    {"xrGetSystemProperties", (PFN_xrVoidFunction)rt_GetSystemProperties, 0},
    {"xrEnumerateViewConfigurations", (PFN_xrVoidFunction)rt_EnumerateViewConfigurations, 0},
    {"xrGetViewConfigurationProperties", (PFN_xrVoidFunction)rt_GetViewConfigurationProperties, 0},
    {"xrEnumerateViewConfigurationViews", (PFN_xrVoidFunction)rt_EnumerateViewConfigurationViews,
     0},
    {"xrEnumerateEnvironmentBlendModes", (PFN_xrVoidFunction)rt_EnumerateEnvironmentBlendModes, 0},
    {"xrGetOpenGLGraphicsRequirementsKHR", (PFN_xrVoidFunction)rt_GetOpenGLGraphicsRequirementsKHR,
     RT_NEEDS_OPENGL},
    {"xrStringToPath", (PFN_xrVoidFunction)rt_StringToPath, 0},
    {"xrPathToString", (PFN_xrVoidFunction)rt_PathToString, 0},
    {"xrEnumerateInstanceExtensionProperties",
     (PFN_xrVoidFunction)rt_EnumerateInstanceExtensionProperties, 0},
    {"xrEnumerateApiLayerProperties", (PFN_xrVoidFunction)rt_EnumerateApiLayerProperties, 0},
    {"xrCreateInstance", (PFN_xrVoidFunction)rt_CreateInstance, 0},
    {NULL, NULL, 0},
};

static XrResult XRAPI_CALL rt_GetInstanceProcAddr(XrInstance instance, const char *name,
                                                  PFN_xrVoidFunction *function) {
    RT_LOCKED;
    const char *F = "xrGetInstanceProcAddr";
    if (!name || !function) return rt_refuse(XR_ERROR_VALIDATION_FAILURE, F, "NULL argument");
    *function = NULL;
    if (instance == XR_NULL_HANDLE) {
        /* without an instance only these three may be asked for */
        if (!strcmp(name, "xrEnumerateInstanceExtensionProperties"))
            *function = (PFN_xrVoidFunction)rt_EnumerateInstanceExtensionProperties;
        else if (!strcmp(name, "xrEnumerateApiLayerProperties"))
            *function = (PFN_xrVoidFunction)rt_EnumerateApiLayerProperties;
        else if (!strcmp(name, "xrCreateInstance"))
            *function = (PFN_xrVoidFunction)rt_CreateInstance;
        else if (!strcmp(name, "xrGetInstanceProcAddr"))
            *function = (PFN_xrVoidFunction)rt_GetInstanceProcAddr;
        else
            return XR_ERROR_HANDLE_INVALID;
        return XR_SUCCESS;
    }
    rt_instance *inst = rt_handle_get(instance, RT_INSTANCE);
    if (!inst) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrInstance");
    if (!strcmp(name, "xrGetInstanceProcAddr")) {
        *function = (PFN_xrVoidFunction)rt_GetInstanceProcAddr;
        return XR_SUCCESS;
    }
    const rt_entry *tables[] = {instance_entries, rt_session_entries, rt_swapchain_entries,
                                rt_action_entries};
    for (size_t t = 0; t < sizeof tables / sizeof *tables; t++)
        for (const rt_entry *e = tables[t]; e->name; e++) {
            if (strcmp(e->name, name)) continue;
            /* an extension's functions exist only when the extension was enabled */
            if ((e->needs & RT_NEEDS_OPENGL) && !inst->ext_opengl)
                return XR_ERROR_FUNCTION_UNSUPPORTED;
            if ((e->needs & RT_NEEDS_EGL) && !inst->ext_egl) return XR_ERROR_FUNCTION_UNSUPPORTED;
            *function = e->fn;
            return XR_SUCCESS;
        }
    /* the loader asks for every function it knows: not an error worth logging */
    return XR_ERROR_FUNCTION_UNSUPPORTED;
}

RT_EXPORT XrResult xrNegotiateLoaderRuntimeInterface(const XrNegotiateLoaderInfo *loaderInfo,
                                                     XrNegotiateRuntimeRequest *request) {
    const char *F = "xrNegotiateLoaderRuntimeInterface";
    if (!loaderInfo || !request ||
        loaderInfo->structType != XR_LOADER_INTERFACE_STRUCT_LOADER_INFO ||
        loaderInfo->structVersion != XR_LOADER_INFO_STRUCT_VERSION ||
        loaderInfo->structSize != sizeof(XrNegotiateLoaderInfo) ||
        request->structType != XR_LOADER_INTERFACE_STRUCT_RUNTIME_REQUEST ||
        request->structVersion != XR_RUNTIME_INFO_STRUCT_VERSION ||
        request->structSize != sizeof(XrNegotiateRuntimeRequest))
        return rt_refuse(XR_ERROR_INITIALIZATION_FAILED, F, "unexpected negotiation structs");
    if (loaderInfo->minInterfaceVersion > XR_CURRENT_LOADER_RUNTIME_VERSION ||
        loaderInfo->maxInterfaceVersion < XR_CURRENT_LOADER_RUNTIME_VERSION)
        return rt_refuse(XR_ERROR_INITIALIZATION_FAILED, F,
                         "loader interface %u..%u excludes version 1",
                         loaderInfo->minInterfaceVersion, loaderInfo->maxInterfaceVersion);
    if (loaderInfo->minApiVersion > RT_API_VERSION ||
        loaderInfo->maxApiVersion < XR_MAKE_VERSION(1, 0, 0))
        return rt_refuse(XR_ERROR_INITIALIZATION_FAILED, F,
                         "the loader's API range excludes OpenXR 1.0");
    request->runtimeInterfaceVersion = XR_CURRENT_LOADER_RUNTIME_VERSION;
    request->runtimeApiVersion = RT_API_VERSION;
    request->getInstanceProcAddr = rt_GetInstanceProcAddr;
    return XR_SUCCESS;
}
