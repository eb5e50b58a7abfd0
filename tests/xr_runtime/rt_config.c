/* The control script: a tiny JSON reader (objects, arrays, numbers, strings, true/false/null)
 * and the defaults, which resemble Monado's simulated HMD but small, with asymmetric FOVs
 * (each eye's outer side wider). */
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "rt.h"

typedef enum { J_NULL, J_BOOL, J_NUM, J_STR, J_ARR, J_OBJ } jtype;
typedef struct jval {
    jtype t;
    double num;
    char *str;
    int n;
    struct jval *items;
    char **keys;
} jval;

typedef struct {
    const char *p;
    const char *err;
} jparser;

static void jfree(jval *v) {
    free(v->str);
    for (int i = 0; i < v->n; i++) {
        jfree(&v->items[i]);
        if (v->keys) free(v->keys[i]);
    }
    free(v->items);
    free(v->keys);
    memset(v, 0, sizeof *v);
}

static void jws(jparser *ps) {
    while (isspace((unsigned char)*ps->p))
        ps->p++;
}

static int jparse(jparser *ps, jval *out);

static char *jstring(jparser *ps) {
    if (*ps->p != '"') {
        ps->err = "expected a string";
        return NULL;
    }
    ps->p++;
    size_t cap = 16, len = 0;
    char *s = malloc(cap);
    while (*ps->p && *ps->p != '"') {
        char c = *ps->p++;
        if (c == '\\') {
            char e = *ps->p++;
            switch (e) {
            case 'n': c = '\n'; break;
            case 't': c = '\t'; break;
            case 'r': c = '\r'; break;
            case 'b': c = '\b'; break;
            case 'f': c = '\f'; break;
            case 'u': /* keep it simple: only ASCII escapes */
                c = (char)strtol((char[]){ps->p[0], ps->p[1], ps->p[2], ps->p[3], 0}, NULL, 16);
                ps->p += 4;
                break;
            case 0:
                ps->err = "unterminated string";
                free(s);
                return NULL;
            default: c = e;
            }
        }
        if (len + 2 > cap) s = realloc(s, cap *= 2);
        s[len++] = c;
    }
    if (*ps->p != '"') {
        ps->err = "unterminated string";
        free(s);
        return NULL;
    }
    ps->p++;
    s[len] = 0;
    return s;
}

static int jparse(jparser *ps, jval *out) {
    memset(out, 0, sizeof *out);
    jws(ps);
    char c = *ps->p;
    if (c == '{' || c == '[') {
        int obj = c == '{';
        out->t = obj ? J_OBJ : J_ARR;
        ps->p++;
        jws(ps);
        if (*ps->p == (obj ? '}' : ']')) {
            ps->p++;
            return 0;
        }
        for (;;) {
            char *key = NULL;
            jws(ps);
            if (obj) {
                if (!(key = jstring(ps))) return -1;
                jws(ps);
                if (*ps->p != ':') {
                    ps->err = "expected ':'";
                    free(key);
                    return -1;
                }
                ps->p++;
            }
            out->items = realloc(out->items, sizeof(jval) * (out->n + 1));
            if (obj) out->keys = realloc(out->keys, sizeof(char *) * (out->n + 1));
            if (obj) out->keys[out->n] = key;
            if (jparse(ps, &out->items[out->n])) {
                out->n++;
                return -1;
            }
            out->n++;
            jws(ps);
            if (*ps->p == ',') {
                ps->p++;
                continue;
            }
            if (*ps->p == (obj ? '}' : ']')) {
                ps->p++;
                return 0;
            }
            ps->err = obj ? "expected ',' or '}'" : "expected ',' or ']'";
            return -1;
        }
    }
    if (c == '"') {
        out->t = J_STR;
        return (out->str = jstring(ps)) ? 0 : -1;
    }
    if (!strncmp(ps->p, "true", 4)) {
        out->t = J_BOOL;
        out->num = 1;
        ps->p += 4;
        return 0;
    }
    if (!strncmp(ps->p, "false", 5)) {
        out->t = J_BOOL;
        ps->p += 5;
        return 0;
    }
    if (!strncmp(ps->p, "null", 4)) {
        out->t = J_NULL;
        ps->p += 4;
        return 0;
    }
    char *end;
    out->t = J_NUM;
    out->num = strtod(ps->p, &end);
    if (end == ps->p) {
        ps->err = "unexpected character";
        return -1;
    }
    ps->p = end;
    return 0;
}

static const jval *jget(const jval *obj, const char *key) {
    if (obj->t != J_OBJ) return NULL;
    for (int i = 0; i < obj->n; i++)
        if (!strcmp(obj->keys[i], key)) return &obj->items[i];
    return NULL;
}

/* numbers of an array into out[0..n); -1 unless it is an array of exactly n numbers */
static int jnums(const jval *v, double *out, int n) {
    if (!v || v->t != J_ARR || v->n != n) return -1;
    for (int i = 0; i < n; i++) {
        if (v->items[i].t != J_NUM) return -1;
        out[i] = v->items[i].num;
    }
    return 0;
}

static const float DEFAULT_FOV[2][4] = {{-0.80f, 0.70f, 0.78f, -0.78f},
                                        {-0.70f, 0.80f, 0.78f, -0.78f}};

void rt_config_load_defaults(rt_config *cfg) {
    memset(cfg, 0, sizeof *cfg);
    cfg->views = 2;
    cfg->eye_w = 96;
    cfg->eye_h = 72;
    cfg->ipd = 0.063;
    for (int i = 0; i < RT_MAX_VIEWS; i++)
        memcpy(cfg->fov[i], DEFAULT_FOV[i % 2], sizeof(float[4]));
    cfg->period_s = 0.05;
    cfg->head_count = 1;
    cfg->head = calloc(1, sizeof(double[7]));
    cfg->head[0][6] = 1.0;
    cfg->format_count = 3;
    cfg->formats[0] = 0x8C43; /* GL_SRGB8_ALPHA8 */
    cfg->formats[1] = 0x8058; /* GL_RGBA8 */
    cfg->formats[2] = 0x881A; /* GL_RGBA16F */
    cfg->extension_count = 2;
    strcpy(cfg->extensions[0], XR_KHR_OPENGL_ENABLE_EXTENSION_NAME);
    strcpy(cfg->extensions[1], XR_MNDX_EGL_ENABLE_EXTENSION_NAME);
    cfg->system_available = 1;
    cfg->lose_after_frames = -1;
}

void rt_config_free(rt_config *cfg) {
    free(cfg->head);
    cfg->head = NULL;
}

#define BAD(...)                                                         \
    do {                                                                 \
        fprintf(stderr, "[BTF test runtime] control script %s: ", path); \
        fprintf(stderr, __VA_ARGS__);                                    \
        fputc('\n', stderr);                                             \
        goto fail;                                                       \
    } while (0)

/* BTF_XR_TEST_PACE_HZ: pace on at that display rate (over the script's period and pace) */
static int pace_from_env(rt_config *cfg) {
    const char *text = getenv("BTF_XR_TEST_PACE_HZ");
    if (!text || !*text) return 0;
    char *end;
    double hz = strtod(text, &end);
    if (*end || !(hz > 0) || hz > 10000) {
        fprintf(stderr, "[BTF test runtime] BTF_XR_TEST_PACE_HZ=%s is not a rate in Hz\n", text);
        return -1;
    }
    cfg->pace = 1;
    cfg->period_s = 1.0 / hz;
    return 0;
}

static int load_script(rt_config *cfg);

int rt_config_load(rt_config *cfg) {
    if (load_script(cfg)) return -1;
    return pace_from_env(cfg);
}

static int load_script(rt_config *cfg) {
    rt_config_load_defaults(cfg);
    const char *path = getenv("BTF_XR_TEST_SCRIPT");
    if (!path || !*path) return 0;
    jval root = {0};
    char *text = NULL;
    FILE *f = fopen(path, "rb");
    if (!f) BAD("cannot be opened");
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    text = calloc(1, size + 1);
    if (fread(text, 1, size, f) != (size_t)size) {
        fclose(f);
        BAD("cannot be read");
    }
    fclose(f);
    jparser ps = {text, NULL};
    if (jparse(&ps, &root)) BAD("is not JSON (%s near byte %ld)", ps.err, (long)(ps.p - text));
    if (root.t != J_OBJ) BAD("is not a JSON object");
    static const char *const KNOWN[] = {
        "views",
        "eye_size",
        "ipd",
        "fov",
        "display_period_s",
        "head",
        "formats",
        "extensions",
        "system_available",
        "lose_session_after_frames",
        "should_render_from",
        "pace",
        "head_motion",
        "strict_teardown",
        "capture_dir",
    };
    for (int i = 0; i < root.n; i++) {
        int ok = 0;
        for (size_t k = 0; k < sizeof KNOWN / sizeof *KNOWN; k++)
            ok |= !strcmp(root.keys[i], KNOWN[k]);
        if (!ok) BAD("unknown key \"%s\" (controller actions are not scripted yet)", root.keys[i]);
    }
    const jval *v;
    double d[7];
    if ((v = jget(&root, "views")) && v->t != J_NULL) {
        if (v->t != J_NUM || v->num < 1 || v->num > RT_MAX_VIEWS)
            BAD("views must be 1..%d", RT_MAX_VIEWS);
        cfg->views = (int)v->num;
    }
    if ((v = jget(&root, "eye_size")) && v->t != J_NULL) {
        if (jnums(v, d, 2) || d[0] < 1 || d[1] < 1) BAD("eye_size must be [width, height]");
        cfg->eye_w = (int)d[0];
        cfg->eye_h = (int)d[1];
    }
    if ((v = jget(&root, "ipd")) && v->t != J_NULL) {
        if (v->t != J_NUM) BAD("ipd must be a number (metres)");
        cfg->ipd = v->num;
    }
    if ((v = jget(&root, "fov")) && v->t != J_NULL) {
        /* {"left": [l, r, u, d], "right": [...]} or a list with one entry per view */
        const jval *sides[RT_MAX_VIEWS] = {0};
        int n = 0;
        if (v->t == J_OBJ) {
            sides[0] = jget(v, "left");
            sides[1] = jget(v, "right");
            n = 2;
        } else if (v->t == J_ARR && v->n <= RT_MAX_VIEWS) {
            for (n = 0; n < v->n; n++)
                sides[n] = &v->items[n];
        } else
            BAD("fov must be {\"left\": [l, r, u, d], \"right\": [...]} or a list per view");
        for (int i = 0; i < n; i++) {
            if (!sides[i]) continue;
            if (jnums(sides[i], d, 4))
                BAD("each fov must be [angleLeft, angleRight, angleUp, angleDown]");
            for (int k = 0; k < 4; k++)
                cfg->fov[i][k] = (float)d[k];
        }
        for (int i = n; i < RT_MAX_VIEWS; i++)
            memcpy(cfg->fov[i], cfg->fov[i % 2], sizeof(float[4]));
    }
    if ((v = jget(&root, "display_period_s")) && v->t != J_NULL) {
        if (v->t != J_NUM || v->num <= 0) BAD("display_period_s must be a positive number");
        cfg->period_s = v->num;
    }
    if ((v = jget(&root, "head")) && v->t != J_NULL) {
        if (v->t != J_ARR || v->n < 1)
            BAD("head must be a non-empty list of [x, y, z, qx, qy, qz, qw]");
        free(cfg->head);
        cfg->head = calloc(v->n, sizeof(double[7]));
        cfg->head_count = v->n;
        for (int i = 0; i < v->n; i++) {
            if (jnums(&v->items[i], cfg->head[i], 7))
                BAD("head[%d] must be [x, y, z, qx, qy, qz, qw]", i);
            double *q = cfg->head[i] + 3;
            double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
            if (norm < 1e-6) BAD("head[%d] has a zero quaternion", i);
            for (int k = 0; k < 4; k++)
                q[k] /= norm;
        }
    }
    if ((v = jget(&root, "formats")) && v->t != J_NULL) {
        if (v->t != J_ARR || v->n > RT_MAX_FORMATS) BAD("formats must be a list of GLenums");
        cfg->format_count = v->n;
        for (int i = 0; i < v->n; i++) {
            if (v->items[i].t != J_NUM) BAD("formats[%d] must be a GLenum number", i);
            cfg->formats[i] = (int64_t)v->items[i].num;
        }
    }
    if ((v = jget(&root, "extensions")) && v->t != J_NULL) {
        if (v->t != J_ARR || v->n > RT_MAX_EXTENSIONS) BAD("extensions must be a list of names");
        cfg->extension_count = v->n;
        for (int i = 0; i < v->n; i++) {
            if (v->items[i].t != J_STR || strlen(v->items[i].str) >= XR_MAX_EXTENSION_NAME_SIZE)
                BAD("extensions[%d] must be an extension name", i);
            strcpy(cfg->extensions[i], v->items[i].str);
        }
    }
    if ((v = jget(&root, "system_available")) && v->t != J_NULL) {
        if (v->t != J_BOOL) BAD("system_available must be true or false");
        cfg->system_available = v->num != 0;
    }
    if ((v = jget(&root, "lose_session_after_frames")) && v->t != J_NULL) {
        if (v->t != J_NUM || v->num < 0) BAD("lose_session_after_frames must be null or >= 0");
        cfg->lose_after_frames = (long)v->num;
    }
    if ((v = jget(&root, "should_render_from")) && v->t != J_NULL) {
        if (v->t != J_STR || (strcmp(v->str, "synchronized") && strcmp(v->str, "visible")))
            BAD("should_render_from must be \"synchronized\" or \"visible\"");
        cfg->render_from_visible = !strcmp(v->str, "visible");
    }
    if ((v = jget(&root, "pace")) && v->t != J_NULL) {
        if (v->t != J_BOOL) BAD("pace must be true or false");
        cfg->pace = v->num != 0;
    }
    if ((v = jget(&root, "head_motion")) && v->t != J_NULL) {
        if (jnums(v, d, 2) || d[0] < 0 || d[1] < 0)
            BAD("head_motion must be [metres, radians], both >= 0");
        cfg->head_motion[0] = d[0];
        cfg->head_motion[1] = d[1];
    }
    if ((v = jget(&root, "strict_teardown")) && v->t != J_NULL) {
        if (v->t == J_STR && !strcmp(v->str, "log"))
            cfg->strict_teardown = 2;
        else if (v->t == J_BOOL)
            cfg->strict_teardown = v->num != 0;
        else
            BAD("strict_teardown must be true, false or \"log\"");
    }
    if ((v = jget(&root, "capture_dir")) && v->t != J_NULL) {
        if (v->t != J_STR || v->str[0] != '/' || strlen(v->str) >= sizeof cfg->capture_dir)
            BAD("capture_dir must be an absolute path");
        strcpy(cfg->capture_dir, v->str);
    }
    jfree(&root);
    free(text);
    return 0;
fail:
    jfree(&root);
    free(text);
    return -1;
}
