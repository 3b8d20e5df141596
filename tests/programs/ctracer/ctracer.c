/*
 * ctracer: a student's Whitted ray tracer in C, written from the scene format (SCENE_FORMAT.md) alone.
 *
 * Build:  gcc -O2 -o ctracer ctracer.c -lz -lm        (trace_core.h is included from this file's folder)
 * Usage:  ctracer SCENE.json OUT.png [--mistake ID]... [--offset X] [--offset-along normal|ray]
 *                                    [--float32] [--ppm]
 *         ctracer --mistakes                 (prints the mistake ids below, one a line)
 *
 * Default: an honest float64 tracer of the whole format: spheres, planes, triangles and meshes (with optional
 * per-vertex normals), ambient, directional, point, spot and area lights, checkers, Phong with opaque shadow
 * rays, Whitted reflection and refraction with total internal reflection, n x n samples per pixel, the
 * background, perspective and orthographic cameras; the pixel is the mean of its samples, clamped to [0, 1]
 * and stored as floor(255 v + 0.5), no gamma.
 *
 * Leaving a surface.  By default a shadow or secondary ray starts off its surface along the surface's
 * geometric normal, towards the side the new ray goes, by eps = REL * (|P|max + t): REL = 1e-9 in double
 * (1e-4 with --float32), |P|max the largest coordinate of the hit point and t the distance the ray travelled
 * to it; the rounding error of P = O + t D is about one ulp of (|O| + t) <= (|P| + 2t), far below eps, so the
 * new ray never finds its own surface again, at any scale.  A shadow ray to a light at distance d ignores
 * hits beyond d - REL * (|light|max + d), so a surface through the light does not block it.
 *
 * Styles (still honest):
 *   --offset X              start shadow and secondary rays X scene units off the hit point along the
 *                           geometric normal, towards the side the new ray goes (instead of eps above)
 *   --offset-along ray      with --offset X: start them at the hit point and ignore hits nearer than t = X
 *   --float32               all geometry and shading in float instead of double
 *   --ppm                   write a binary PPM (P6) instead of a PNG
 *
 * Mistakes (--mistake ID, repeatable), each made the way a student makes it:
 *   no-shadows              no shadow rays at all
 *   shadow-acne             no offset at all: shadow and secondary rays start at P with t > 0
 *   blinn-phong             max(0, N.H)^n with H = unit(L + V) instead of the reflected vector
 *   specular-behind         the light is not skipped where N.L <= 0: diffuse clamps to 0, specular stays
 *   gamma                   pow(v, 1/2.2) after the clamp
 *   no-attenuation          point, spot and area lights without their attenuation
 *   no-ambient              no ambient term
 *   no-specular             no specular term
 *   normals-not-flipped     N is never turned to face the ray
 *   image-flipped           y = (2 sy - 1) h: rows upside down
 *   no-half-pixel           sample at (i + a/n)/W: the pixel's corner, without the + 0.5
 *   camera-up-as-given      u = unit(up) as the scene gives it, not r x f
 *   horizontal-fov          fov read as horizontal: x = (2 sx - 1) h, y = (1 - 2 sy) h H/W
 *   aspect-inverted         the aspect upside down: x = (2 sx - 1) h H/W
 *   area-not-divided        each area-light sample shines with the whole colour
 *   area-samples-at-corners each area-light sample at corner + (i/nu) eu + (j/nv) ev, without the + 0.5
 *   spot-radians            cos(cutoff) with the cutoff in degrees passed as radians
 *   spot-ramp-angle         the inner-to-outer ramp linear in the angle, not in its cosine
 *   depth-plus-one          recursion while depth <= max_depth
 *   depth-minus-one         recursion while depth < max_depth - 1
 *   ior-inverted            eta = ior entering and 1/ior leaving
 *   offset-too-large        rays leave by 2e-2 of the scene's size along the normal
 *   reflect-sign            R = L - 2(N.L)N (the reflect() of a textbook applied to L, not -L)
 *   checker-ignored         every point shaded with its object's own material
 *   checker-truncated       the cell index (long long)(x / s), toward 0, not floor(x / s)
 *   colours-not-clamped     (unsigned char)(int)(255 v + 0.5): values above 1 wrap around
 *   ambient-from-diffuse    the ambient light times k_d instead of k_a
 *   transparent-no-shadows  the shadow loop skips objects whose material has k_t > 0
 *   no-reflection           mirror rays never traced
 *   bounce-miss-black       a mirror or refracted ray that misses returns black, not the background
 *   no-refraction           refracted rays never traced
 *   left-handed             r = unit(up x f), u = f x r: the image mirrored left to right
 *   samples-ignored         one sample per pixel, whatever image.samples says
 *   bgr                     the channels written blue, green, red
 *   normals-not-normalised  a mesh's blend of vertex normals used as it is, never made unit
 *
 * The scene is trusted (it is the course's): this reads what the format says and does not validate it all.
 */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* ------------------------------------------------------------------ a small JSON reader */

enum { J_NULL, J_BOOL, J_NUM, J_STR, J_ARR, J_OBJ };

typedef struct JNode {
    int type;
    double num;
    char *str;
    int n;
    char **keys;
    struct JNode **items;
} JNode;

typedef struct {
    const char *s;
    size_t at, len;
} JIn;

static void die(const char *what, const char *detail) {
    fprintf(stderr, "ctracer: %s%s%s\n", what, detail ? ": " : "", detail ? detail : "");
    exit(2);
}

static void *grow(void *p, size_t n) {
    void *q = realloc(p, n ? n : 1);
    if (!q) die("out of memory", NULL);
    return q;
}

static void skip_space(JIn *in) {
    while (in->at < in->len && isspace((unsigned char)in->s[in->at])) in->at++;
}

static JNode *jnew(int type) {
    JNode *node = calloc(1, sizeof *node);
    if (!node) die("out of memory", NULL);
    node->type = type;
    return node;
}

static JNode *parse_value(JIn *in);

static char *parse_string(JIn *in) {
    size_t cap = 16, n = 0;
    char *out = grow(NULL, cap);
    in->at++; /* the opening quote */
    for (;;) {
        if (in->at >= in->len) die("JSON", "unterminated string");
        char c = in->s[in->at++];
        if (c == '"') break;
        if (c == '\\') {
            if (in->at >= in->len) die("JSON", "bad escape");
            char e = in->s[in->at++];
            switch (e) {
            case 'n': c = '\n'; break;
            case 't': c = '\t'; break;
            case 'r': c = '\r'; break;
            case 'b': c = '\b'; break;
            case 'f': c = '\f'; break;
            case 'u': in->at += 4; c = '?'; break; /* names here are ASCII; anything else is kept as '?' */
            default: c = e;
            }
        }
        if (n + 2 > cap) out = grow(out, cap *= 2);
        out[n++] = c;
    }
    out[n] = 0;
    return out;
}

static void add_item(JNode *node, char *key, JNode *item) {
    node->items = grow(node->items, (node->n + 1) * sizeof *node->items);
    node->keys = grow(node->keys, (node->n + 1) * sizeof *node->keys);
    node->items[node->n] = item;
    node->keys[node->n] = key;
    node->n++;
}

static JNode *parse_container(JIn *in, int type) {
    JNode *node = jnew(type);
    char close = type == J_ARR ? ']' : '}';
    in->at++;
    skip_space(in);
    if (in->at < in->len && in->s[in->at] == close) {
        in->at++;
        return node;
    }
    for (;;) {
        char *key = NULL;
        skip_space(in);
        if (type == J_OBJ) {
            if (in->at >= in->len || in->s[in->at] != '"') die("JSON", "expected a key");
            key = parse_string(in);
            skip_space(in);
            if (in->at >= in->len || in->s[in->at] != ':') die("JSON", "expected ':'");
            in->at++;
        }
        add_item(node, key, parse_value(in));
        skip_space(in);
        if (in->at >= in->len) die("JSON", "unexpected end");
        char c = in->s[in->at++];
        if (c == close) return node;
        if (c != ',') die("JSON", "expected ',' or the end of a list");
    }
}

static int word(JIn *in, const char *w) {
    size_t n = strlen(w);
    if (in->at + n <= in->len && strncmp(in->s + in->at, w, n) == 0) {
        in->at += n;
        return 1;
    }
    return 0;
}

static JNode *parse_value(JIn *in) {
    skip_space(in);
    if (in->at >= in->len) die("JSON", "unexpected end");
    char c = in->s[in->at];
    if (c == '{') return parse_container(in, J_OBJ);
    if (c == '[') return parse_container(in, J_ARR);
    if (c == '"') {
        JNode *node = jnew(J_STR);
        node->str = parse_string(in);
        return node;
    }
    if (word(in, "true") || word(in, "false")) {
        JNode *node = jnew(J_BOOL);
        node->num = in->s[in->at - 1] == 'e' && in->s[in->at - 2] == 'u';
        return node;
    }
    if (word(in, "null")) return jnew(J_NULL);
    char *end;
    double v = strtod(in->s + in->at, &end);
    if (end == in->s + in->at) die("JSON", "unexpected character");
    in->at = (size_t)(end - in->s);
    JNode *node = jnew(J_NUM);
    node->num = v;
    return node;
}

static JNode *jget(const JNode *obj, const char *key) {
    if (!obj || obj->type != J_OBJ) return NULL;
    for (int k = 0; k < obj->n; k++)
        if (strcmp(obj->keys[k], key) == 0) return obj->items[k];
    return NULL;
}

static double jnum(const JNode *obj, const char *key, double fallback) {
    const JNode *v = jget(obj, key);
    if (!v || v->type == J_NULL) return fallback;
    if (v->type != J_NUM) die("not a number", key);
    return v->num;
}

static void jvec(const JNode *obj, const char *key, double out[3], const double *fallback) {
    const JNode *v = jget(obj, key);
    if (!v) {
        if (!fallback) die("missing", key);
        memcpy(out, fallback, 3 * sizeof(double));
        return;
    }
    if (v->type == J_NUM) { /* a colour given as one number k means [k, k, k] */
        out[0] = out[1] = out[2] = v->num;
        return;
    }
    if (v->type != J_ARR || v->n != 3) die("not a 3-vector", key);
    for (int k = 0; k < 3; k++) out[k] = v->items[k]->num;
}

/* ------------------------------------------------------------------ the scene, as read (double) */

enum { O_SPHERE, O_PLANE, O_TRIANGLE, O_MESH };
enum { L_AMBIENT, L_DIRECTIONAL, L_POINT, L_SPOT, L_AREA };

typedef struct {
    char *name;
    double ka[3], kd[3], ks[3], shininess, kr, kt, ior, cell;
    char *checker; /* the other material's name, or NULL */
    int other;
} Material;

typedef struct {
    int type, material;
    double center[3], radius, point[3], normal[3];
    int nverts, nfaces;
    double *verts, *normals; /* normals: NULL or one per vertex */
    int *faces;
} Object;

typedef struct {
    int type;
    double color[3], position[3], direction[3], attenuation[3];
    double cutoff, inner, exponent;
    double corner[3], eu[3], ev[3];
    int nu, nv;
} Light;

typedef struct {
    int ortho, width, height, samples, max_depth;
    double eye[3], look_at[3], up[3], fov, view_height, background[3];
    int nmat, nobj, nlight;
    Material *mats;
    Object *objs;
    Light *lights;
} Scene;

/* what the command line asks for */
typedef struct {
    int mistake[64]; /* by M_ index (M_COUNT of them, checked below) */
    double offset; /* < 0: the careful relative offset */
    int along_ray, float32, ppm;
} Options;

enum {
    M_NO_SHADOWS, M_SHADOW_ACNE, M_BLINN, M_SPEC_BEHIND, M_GAMMA, M_NO_ATTEN, M_NO_AMBIENT, M_NO_SPECULAR,
    M_NOT_FLIPPED, M_IMAGE_FLIPPED, M_NO_HALF, M_HFOV, M_ASPECT_INVERTED, M_UP_AS_GIVEN, M_AREA_NOT_DIVIDED,
    M_AREA_AT_CORNERS,
    M_SPOT_RADIANS, M_DEPTH_PLUS, M_DEPTH_MINUS, M_IOR_INVERTED, M_OFFSET_LARGE, M_REFLECT_SIGN, M_CHECKER_IGNORED,
    M_CHECKER_TRUNCATED, M_NOT_CLAMPED, M_AMBIENT_KD, M_SPOT_RAMP_ANGLE, M_TRANSPARENT_NO_SHADOWS, M_NO_REFLECTION,
    M_MISS_BLACK, M_NO_REFRACTION, M_LEFT_HANDED, M_SAMPLES_IGNORED, M_BGR, M_NOT_NORMALISED, M_COUNT
};

_Static_assert(M_COUNT <= 64, "Options.mistake holds every mistake");

static const char *MISTAKE_IDS[M_COUNT] = {
    "no-shadows", "shadow-acne", "blinn-phong", "specular-behind", "gamma", "no-attenuation", "no-ambient",
    "no-specular", "normals-not-flipped", "image-flipped", "no-half-pixel", "horizontal-fov", "aspect-inverted",
    "camera-up-as-given", "area-not-divided", "area-samples-at-corners", "spot-radians", "depth-plus-one", "depth-minus-one",
    "ior-inverted", "offset-too-large", "reflect-sign", "checker-ignored", "checker-truncated", "colours-not-clamped",
    "ambient-from-diffuse", "spot-ramp-angle", "transparent-no-shadows", "no-reflection", "bounce-miss-black",
    "no-refraction",
    "left-handed", "samples-ignored", "bgr", "normals-not-normalised",
};

static char *read_file(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) die("cannot open", path);
    size_t cap = 1 << 16, n = 0, got;
    char *buf = grow(NULL, cap);
    while ((got = fread(buf + n, 1, cap - n, f)) > 0) {
        n += got;
        if (n == cap) buf = grow(buf, cap *= 2);
    }
    fclose(f);
    *len = n;
    return buf;
}

static const double ZERO[3] = {0, 0, 0}, ATTEN[3] = {1, 0, 0}, UP[3] = {0, 1, 0};

static void read_material(Material *m, const char *name, const JNode *j) {
    static const double KA[3] = {0.3, 0.3, 0.3}, KD[3] = {0.5, 0.5, 0.5}, KS[3] = {0.8, 0.8, 0.8};
    m->name = (char *)name;
    jvec(j, "ambient", m->ka, KA);
    jvec(j, "diffuse", m->kd, KD);
    jvec(j, "specular", m->ks, KS);
    m->shininess = jnum(j, "shininess", 100);
    m->kr = jnum(j, "reflectance", 0);
    m->kt = jnum(j, "transmittance", 0);
    m->ior = jnum(j, "ior", 1.5);
    const JNode *c = jget(j, "checker");
    m->checker = NULL;
    m->other = -1;
    if (c && c->type == J_OBJ) {
        m->cell = jnum(c, "size", 1);
        const JNode *other = jget(c, "material");
        if (!other || other->type != J_STR) die("checker without a material", name);
        m->checker = other->str;
    }
}

static int find_material(const Scene *s, const char *name) {
    for (int k = 0; k < s->nmat; k++)
        if (strcmp(s->mats[k].name, name) == 0) return k;
    die("unknown material", name);
    return -1;
}

static void read_points(const JNode *list, int *count, double **out, const char *what) {
    if (!list || list->type != J_ARR) die("missing", what);
    *count = list->n;
    *out = grow(NULL, 3 * sizeof(double) * (size_t)list->n);
    for (int k = 0; k < list->n; k++) {
        const JNode *p = list->items[k];
        if (p->type != J_ARR || p->n != 3) die("not a 3-vector", what);
        for (int c = 0; c < 3; c++) (*out)[3 * k + c] = p->items[c]->num;
    }
}

static void read_object(const Scene *s, Object *o, const JNode *j) {
    const JNode *type = jget(j, "type"), *mat = jget(j, "material");
    if (!type || type->type != J_STR || !mat || mat->type != J_STR) die("object without type or material", NULL);
    memset(o, 0, sizeof *o);
    o->material = find_material(s, mat->str);
    if (strcmp(type->str, "sphere") == 0) {
        o->type = O_SPHERE;
        jvec(j, "center", o->center, NULL);
        o->radius = jnum(j, "radius", 1);
    } else if (strcmp(type->str, "plane") == 0) {
        o->type = O_PLANE;
        jvec(j, "point", o->point, NULL);
        jvec(j, "normal", o->normal, NULL);
    } else if (strcmp(type->str, "triangle") == 0 || strcmp(type->str, "mesh") == 0) {
        int n;
        o->type = type->str[0] == 't' ? O_TRIANGLE : O_MESH;
        read_points(jget(j, "vertices"), &o->nverts, &o->verts, "vertices");
        if (o->type == O_TRIANGLE) {
            if (o->nverts != 3) die("a triangle has three vertices", NULL);
            o->nfaces = 1;
            o->faces = grow(NULL, 3 * sizeof(int));
            o->faces[0] = 0, o->faces[1] = 1, o->faces[2] = 2;
            return;
        }
        const JNode *faces = jget(j, "faces");
        if (!faces || faces->type != J_ARR) die("mesh without faces", NULL);
        o->nfaces = faces->n;
        o->faces = grow(NULL, 3 * sizeof(int) * (size_t)faces->n);
        for (int k = 0; k < faces->n; k++)
            for (int c = 0; c < 3; c++) {
                int v = (int)faces->items[k]->items[c]->num;
                if (v < 0 || v >= o->nverts) die("face index out of range", NULL);
                o->faces[3 * k + c] = v;
            }
        if (jget(j, "normals")) {
            read_points(jget(j, "normals"), &n, &o->normals, "normals");
            if (n != o->nverts) die("one normal per vertex", NULL);
        }
    } else {
        die("unknown object type", type->str);
    }
}

static void read_light(Light *l, const JNode *j) {
    const JNode *type = jget(j, "type");
    if (!type || type->type != J_STR) die("light without a type", NULL);
    memset(l, 0, sizeof *l);
    jvec(j, "color", l->color, NULL);
    jvec(j, "attenuation", l->attenuation, ATTEN);
    const char *t = type->str;
    if (strcmp(t, "ambient") == 0) {
        l->type = L_AMBIENT;
    } else if (strcmp(t, "directional") == 0) {
        l->type = L_DIRECTIONAL;
        jvec(j, "direction", l->direction, NULL);
    } else if (strcmp(t, "point") == 0) {
        l->type = L_POINT;
        jvec(j, "position", l->position, NULL);
    } else if (strcmp(t, "spot") == 0) {
        l->type = L_SPOT;
        jvec(j, "position", l->position, NULL);
        jvec(j, "direction", l->direction, NULL);
        l->cutoff = jnum(j, "cutoff", 45);
        l->inner = jnum(j, "inner_cutoff", l->cutoff);
        l->exponent = jnum(j, "exponent", 1);
    } else if (strcmp(t, "area") == 0) {
        l->type = L_AREA;
        jvec(j, "corner", l->corner, NULL);
        jvec(j, "edge_u", l->eu, NULL);
        jvec(j, "edge_v", l->ev, NULL);
        const JNode *samples = jget(j, "samples");
        l->nu = l->nv = 4;
        if (samples && samples->type == J_ARR && samples->n == 2) {
            l->nu = (int)samples->items[0]->num;
            l->nv = (int)samples->items[1]->num;
        }
    } else {
        die("unknown light type", t);
    }
}

static void read_scene(Scene *s, const JNode *root) {
    const JNode *cam = jget(root, "camera"), *img = jget(root, "image");
    if (!cam || !img) die("a scene needs camera and image", NULL);
    memset(s, 0, sizeof *s);
    const JNode *type = jget(cam, "type");
    s->ortho = type && type->type == J_STR && strcmp(type->str, "orthographic") == 0;
    jvec(cam, "position", s->eye, NULL);
    jvec(cam, "look_at", s->look_at, NULL);
    jvec(cam, "up", s->up, UP);
    s->fov = jnum(cam, "fov", 60);
    s->view_height = jnum(cam, "height", 2);
    s->width = (int)jnum(img, "width", 0);
    s->height = (int)jnum(img, "height", 0);
    if (s->width < 1 || s->height < 1) die("image: width and height are required", NULL);
    s->samples = (int)jnum(img, "samples", 1);
    s->max_depth = (int)jnum(img, "max_depth", 4);
    jvec(img, "background", s->background, ZERO);

    const JNode *mats = jget(root, "materials"), *objs = jget(root, "objects"), *lights = jget(root, "lights");
    s->nmat = mats && mats->type == J_OBJ ? mats->n : 0;
    s->mats = grow(NULL, sizeof(Material) * (size_t)s->nmat);
    for (int k = 0; k < s->nmat; k++) read_material(&s->mats[k], mats->keys[k], mats->items[k]);
    for (int k = 0; k < s->nmat; k++)
        if (s->mats[k].checker) s->mats[k].other = find_material(s, s->mats[k].checker);
    s->nobj = objs && objs->type == J_ARR ? objs->n : 0;
    s->objs = grow(NULL, sizeof(Object) * (size_t)s->nobj);
    for (int k = 0; k < s->nobj; k++) read_object(s, &s->objs[k], objs->items[k]);
    s->nlight = lights && lights->type == J_ARR ? lights->n : 0;
    s->lights = grow(NULL, sizeof(Light) * (size_t)s->nlight);
    for (int k = 0; k < s->nlight; k++) read_light(&s->lights[k], lights->items[k]);
}

/* The largest side of the box around the spheres, triangles and meshes (planes not counted; 1 with none). */
static double scene_size(const Scene *s) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int any = 0;
    for (int k = 0; k < s->nobj; k++) {
        const Object *o = &s->objs[k];
        if (o->type == O_SPHERE) {
            for (int c = 0; c < 3; c++) {
                lo[c] = fmin(lo[c], o->center[c] - o->radius);
                hi[c] = fmax(hi[c], o->center[c] + o->radius);
            }
            any = 1;
        } else if (o->type != O_PLANE) {
            for (int v = 0; v < o->nverts; v++)
                for (int c = 0; c < 3; c++) {
                    lo[c] = fmin(lo[c], o->verts[3 * v + c]);
                    hi[c] = fmax(hi[c], o->verts[3 * v + c]);
                }
            any = any || o->nverts > 0;
        }
    }
    if (!any) return 1;
    double side = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    return side > 0 ? side : 1;
}

/* ------------------------------------------------------------------ the tracer, in double and in float */

#define real double
#define SUFFIX _d
#define REL 1e-9
#include "trace_core.h"
#undef real
#undef SUFFIX
#undef REL

#define real float
#define SUFFIX _f
#define REL 1e-4f
#define F32 1
#include "trace_core.h"
#undef F32
#undef real
#undef SUFFIX
#undef REL

/* ------------------------------------------------------------------ writing the image */

static void put32(unsigned char *p, unsigned long v) {
    p[0] = (unsigned char)(v >> 24), p[1] = (unsigned char)(v >> 16);
    p[2] = (unsigned char)(v >> 8), p[3] = (unsigned char)v;
}

static void chunk(FILE *f, const char *type, const unsigned char *data, unsigned long len) {
    unsigned char head[8];
    put32(head, len);
    memcpy(head + 4, type, 4);
    unsigned long crc = crc32(0L, (const Bytef *)type, 4);
    if (len) crc = crc32(crc, data, (uInt)len);
    fwrite(head, 1, 8, f);
    if (len) fwrite(data, 1, len, f);
    put32(head, crc);
    fwrite(head, 1, 4, f);
}

static void write_png(const char *path, const unsigned char *rgb, int w, int h) {
    static const unsigned char SIGNATURE[8] = {137, 80, 78, 71, 13, 10, 26, 10};
    size_t row = 3 * (size_t)w + 1, raw_len = row * (size_t)h;
    unsigned char *raw = grow(NULL, raw_len);
    for (int y = 0; y < h; y++) {
        raw[y * row] = 0; /* filter: none */
        memcpy(raw + y * row + 1, rgb + (size_t)y * 3 * (size_t)w, 3 * (size_t)w);
    }
    uLongf packed_len = compressBound((uLong)raw_len);
    unsigned char *packed = grow(NULL, packed_len);
    if (compress2(packed, &packed_len, raw, (uLong)raw_len, 6) != Z_OK) die("zlib failed", NULL);
    unsigned char ihdr[13];
    put32(ihdr, (unsigned long)w);
    put32(ihdr + 4, (unsigned long)h);
    ihdr[8] = 8, ihdr[9] = 2, ihdr[10] = 0, ihdr[11] = 0, ihdr[12] = 0; /* 8-bit RGB, no interlace */
    FILE *f = fopen(path, "wb");
    if (!f) die("cannot write", path);
    fwrite(SIGNATURE, 1, 8, f);
    chunk(f, "IHDR", ihdr, 13);
    chunk(f, "IDAT", packed, packed_len);
    chunk(f, "IEND", NULL, 0);
    if (fclose(f) != 0) die("cannot write", path);
    free(raw);
    free(packed);
}

static void write_ppm(const char *path, const unsigned char *rgb, int w, int h) {
    FILE *f = fopen(path, "wb");
    if (!f) die("cannot write", path);
    fprintf(f, "P6\n%d %d\n255\n", w, h);
    fwrite(rgb, 1, 3 * (size_t)w * (size_t)h, f);
    if (fclose(f) != 0) die("cannot write", path);
}

/* ------------------------------------------------------------------ the command line */

static void usage(void) {
    fprintf(stderr, "usage: ctracer SCENE.json OUT.png [--mistake ID]... [--offset X] [--offset-along normal|ray]"
                    " [--float32] [--ppm]\n");
    exit(2);
}

static void parse_args(int argc, char **argv, Options *opt, const char **scene, const char **out) {
    int positional = 0;
    if (argc == 2 && strcmp(argv[1], "--mistakes") == 0) {
        for (int m = 0; m < M_COUNT; m++) printf("%s\n", MISTAKE_IDS[m]);
        exit(0);
    }
    memset(opt, 0, sizeof *opt);
    opt->offset = -1;
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k];
        if (strcmp(a, "--mistake") == 0 && k + 1 < argc) {
            const char *id = argv[++k];
            int found = 0;
            for (int m = 0; m < M_COUNT; m++)
                if (strcmp(id, MISTAKE_IDS[m]) == 0) opt->mistake[m] = found = 1;
            if (!found) die("no such mistake", id);
        } else if (strcmp(a, "--offset") == 0 && k + 1 < argc) {
            opt->offset = strtod(argv[++k], NULL);
            if (!(opt->offset >= 0)) die("--offset must be >= 0", argv[k]);
        } else if (strcmp(a, "--offset-along") == 0 && k + 1 < argc) {
            const char *along = argv[++k];
            if (strcmp(along, "ray") != 0 && strcmp(along, "normal") != 0) die("--offset-along", along);
            opt->along_ray = strcmp(along, "ray") == 0;
        } else if (strcmp(a, "--float32") == 0) {
            opt->float32 = 1;
        } else if (strcmp(a, "--ppm") == 0) {
            opt->ppm = 1;
        } else if (a[0] == '-' && a[1] == '-') {
            usage();
        } else if (positional == 0) {
            *scene = a, positional++;
        } else if (positional == 1) {
            *out = a, positional++;
        } else {
            usage();
        }
    }
    if (positional != 2) usage();
    if (opt->along_ray && opt->offset < 0) die("--offset-along ray needs --offset X", NULL);
}

int main(int argc, char **argv) {
    const char *scene_path = NULL, *out_path = NULL;
    Options opt;
    parse_args(argc, argv, &opt, &scene_path, &out_path);
    size_t len;
    char *text = read_file(scene_path, &len);
    JIn in = {text, 0, len};
    JNode *root = parse_value(&in);
    skip_space(&in);
    if (in.at != len) die("JSON", "trailing characters");
    Scene scene;
    read_scene(&scene, root);
    if (opt.mistake[M_OFFSET_LARGE]) {
        opt.offset = 2e-2 * scene_size(&scene);
        opt.along_ray = 0;
    }
    unsigned char *rgb = grow(NULL, 3 * (size_t)scene.width * (size_t)scene.height);
    if (opt.float32)
        render_f(&scene, &opt, rgb);
    else
        render_d(&scene, &opt, rgb);
    if (opt.mistake[M_BGR])
        for (size_t p = 0; p < (size_t)scene.width * (size_t)scene.height; p++) {
            unsigned char r = rgb[3 * p];
            rgb[3 * p] = rgb[3 * p + 2];
            rgb[3 * p + 2] = r;
        }
    if (opt.ppm)
        write_ppm(out_path, rgb, scene.width, scene.height);
    else
        write_png(out_path, rgb, scene.width, scene.height);
    return 0;
}
