/* The BTF test OpenXR runtime: the action API. No controller is ever connected: everything
 * succeeds and every action state is inactive (the spec's answer when no device is bound). */
#include <stdlib.h>
#include <string.h>

#include "rt.h"

static XrResult XRAPI_CALL rt_CreateActionSet(XrInstance instance,
                                              const XrActionSetCreateInfo *info, XrActionSet *out) {
    RT_LOCKED;
    const char *F = "xrCreateActionSet";
    if (!rt_handle_get(instance, RT_INSTANCE))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrInstance");
    RT_CHECK_TYPE(info, XR_TYPE_ACTION_SET_CREATE_INFO, F);
    if (!info->actionSetName[0])
        return rt_refuse(XR_ERROR_NAME_INVALID, F, "actionSetName is empty");
    if (!info->localizedActionSetName[0])
        return rt_refuse(XR_ERROR_LOCALIZED_NAME_INVALID, F, "localizedActionSetName is empty");
    rt_simple *o = calloc(1, sizeof *o);
    o->kind = RT_ACTION_SET;
    o->owner = (void *)instance;
    rt_handle_add(o);
    *out = (XrActionSet)o;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_CreateAction(XrActionSet set, const XrActionCreateInfo *info,
                                           XrAction *out) {
    RT_LOCKED;
    const char *F = "xrCreateAction";
    if (!rt_handle_get(set, RT_ACTION_SET))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrActionSet");
    RT_CHECK_TYPE(info, XR_TYPE_ACTION_CREATE_INFO, F);
    if (!info->actionName[0]) return rt_refuse(XR_ERROR_NAME_INVALID, F, "actionName is empty");
    rt_simple *o = calloc(1, sizeof *o);
    o->kind = RT_ACTION;
    o->owner = (void *)set;
    rt_handle_add(o);
    *out = (XrAction)o;
    return XR_SUCCESS;
}

void rt_action_set_free(rt_simple *set) {
    rt_simple *child; /* its actions go with it */
    while ((child = rt_handle_find_child(RT_ACTION, set))) {
        rt_handle_remove(child);
        free(child);
    }
    rt_handle_remove(set);
    free(set);
}

static XrResult destroy(const void *handle, rt_kind kind, const char *F) {
    RT_LOCKED;
    rt_simple *o = rt_handle_get(handle, kind);
    if (!o) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live handle");
    if (kind == RT_ACTION_SET) {
        rt_action_set_free(o);
        return XR_SUCCESS;
    }
    rt_handle_remove(o);
    free(o);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_DestroyActionSet(XrActionSet set) {
    return destroy(set, RT_ACTION_SET, "xrDestroyActionSet");
}
static XrResult XRAPI_CALL rt_DestroyAction(XrAction action) {
    return destroy(action, RT_ACTION, "xrDestroyAction");
}

static XrResult XRAPI_CALL rt_SuggestInteractionProfileBindings(
    XrInstance instance, const XrInteractionProfileSuggestedBinding *b) {
    RT_LOCKED;
    const char *F = "xrSuggestInteractionProfileBindings";
    if (!rt_handle_get(instance, RT_INSTANCE))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrInstance");
    RT_CHECK_TYPE(b, XR_TYPE_INTERACTION_PROFILE_SUGGESTED_BINDING, F);
    for (uint32_t i = 0; i < b->countSuggestedBindings; i++)
        if (!rt_handle_get(b->suggestedBindings[i].action, RT_ACTION))
            return rt_refuse(XR_ERROR_HANDLE_INVALID, F,
                             "suggestedBindings[%u].action is not a live XrAction", i);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_AttachSessionActionSets(XrSession session,
                                                      const XrSessionActionSetsAttachInfo *info) {
    RT_LOCKED;
    const char *F = "xrAttachSessionActionSets";
    if (!rt_handle_get(session, RT_SESSION))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSession");
    RT_CHECK_TYPE(info, XR_TYPE_SESSION_ACTION_SETS_ATTACH_INFO, F);
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_SyncActions(XrSession session, const XrActionsSyncInfo *info) {
    RT_LOCKED;
    const char *F = "xrSyncActions";
    rt_session *s = rt_handle_get(session, RT_SESSION);
    if (!s) return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSession");
    RT_CHECK_TYPE(info, XR_TYPE_ACTIONS_SYNC_INFO, F);
    if (s->lost) return rt_refuse(XR_ERROR_SESSION_LOST, F, "the session is in LOSS_PENDING");
    return s->state == XR_SESSION_STATE_FOCUSED ? XR_SUCCESS : XR_SESSION_NOT_FOCUSED;
}

#define STATE_GETTER(fn, xr_name, Type, TYPE_ENUM)                                     \
    static XrResult XRAPI_CALL fn(XrSession session, const XrActionStateGetInfo *info, \
                                  Type *state) {                                       \
        RT_LOCKED;                                                                     \
        const char *F = xr_name;                                                       \
        if (!rt_handle_get(session, RT_SESSION))                                       \
            return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSession");      \
        RT_CHECK_TYPE(info, XR_TYPE_ACTION_STATE_GET_INFO, F);                         \
        RT_CHECK_TYPE(state, TYPE_ENUM, F);                                            \
        if (!rt_handle_get(info->action, RT_ACTION))                                   \
            return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrAction");       \
        void *next = state->next;                                                      \
        memset(state, 0, sizeof *state);                                               \
        state->type = TYPE_ENUM;                                                       \
        state->next = next;                                                            \
        return XR_SUCCESS;                                                             \
    }

STATE_GETTER(rt_GetActionStateBoolean, "xrGetActionStateBoolean", XrActionStateBoolean,
             XR_TYPE_ACTION_STATE_BOOLEAN)
STATE_GETTER(rt_GetActionStateFloat, "xrGetActionStateFloat", XrActionStateFloat,
             XR_TYPE_ACTION_STATE_FLOAT)
STATE_GETTER(rt_GetActionStateVector2f, "xrGetActionStateVector2f", XrActionStateVector2f,
             XR_TYPE_ACTION_STATE_VECTOR2F)
STATE_GETTER(rt_GetActionStatePose, "xrGetActionStatePose", XrActionStatePose,
             XR_TYPE_ACTION_STATE_POSE)

static XrResult XRAPI_CALL rt_GetCurrentInteractionProfile(XrSession session,
                                                           XrPath topLevelUserPath,
                                                           XrInteractionProfileState *state) {
    RT_LOCKED;
    const char *F = "xrGetCurrentInteractionProfile";
    (void)topLevelUserPath;
    if (!rt_handle_get(session, RT_SESSION))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, F, "not a live XrSession");
    RT_CHECK_TYPE(state, XR_TYPE_INTERACTION_PROFILE_STATE, F);
    state->interactionProfile = XR_NULL_PATH;
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_ApplyHapticFeedback(XrSession session, const XrHapticActionInfo *info,
                                                  const XrHapticBaseHeader *haptic) {
    RT_LOCKED;
    (void)info;
    (void)haptic;
    if (!rt_handle_get(session, RT_SESSION))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, "xrApplyHapticFeedback", "not a live XrSession");
    return XR_SUCCESS;
}

static XrResult XRAPI_CALL rt_StopHapticFeedback(XrSession session,
                                                 const XrHapticActionInfo *info) {
    RT_LOCKED;
    (void)info;
    if (!rt_handle_get(session, RT_SESSION))
        return rt_refuse(XR_ERROR_HANDLE_INVALID, "xrStopHapticFeedback", "not a live XrSession");
    return XR_SUCCESS;
}

const rt_entry rt_action_entries[] = {
    {"xrCreateActionSet", (PFN_xrVoidFunction)rt_CreateActionSet, 0},
    {"xrDestroyActionSet", (PFN_xrVoidFunction)rt_DestroyActionSet, 0},
    {"xrCreateAction", (PFN_xrVoidFunction)rt_CreateAction, 0},
    {"xrDestroyAction", (PFN_xrVoidFunction)rt_DestroyAction, 0},
    {"xrSuggestInteractionProfileBindings",
     (PFN_xrVoidFunction)rt_SuggestInteractionProfileBindings, 0},
    {"xrAttachSessionActionSets", (PFN_xrVoidFunction)rt_AttachSessionActionSets, 0},
    {"xrSyncActions", (PFN_xrVoidFunction)rt_SyncActions, 0},
    {"xrGetActionStateBoolean", (PFN_xrVoidFunction)rt_GetActionStateBoolean, 0},
    {"xrGetActionStateFloat", (PFN_xrVoidFunction)rt_GetActionStateFloat, 0},
    {"xrGetActionStateVector2f", (PFN_xrVoidFunction)rt_GetActionStateVector2f, 0},
    {"xrGetActionStatePose", (PFN_xrVoidFunction)rt_GetActionStatePose, 0},
    {"xrGetCurrentInteractionProfile", (PFN_xrVoidFunction)rt_GetCurrentInteractionProfile, 0},
    {"xrApplyHapticFeedback", (PFN_xrVoidFunction)rt_ApplyHapticFeedback, 0},
    {"xrStopHapticFeedback", (PFN_xrVoidFunction)rt_StopHapticFeedback, 0},
    {NULL, NULL, 0},
};
