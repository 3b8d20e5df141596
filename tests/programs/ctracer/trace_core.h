/*
 * The tracer itself, written once for a number type `real` and included twice by ctracer.c: as double
 * (SUFFIX _d) and as float (SUFFIX _f, for --float32).  Every name below gets the suffix, so the two copies
 * live side by side; every constant is cast to `real`, so the float copy computes in float throughout.
 */
#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define vec CAT(vec, SUFFIX)
#define v3 CAT(v3, SUFFIX)
#define vadd CAT(vadd, SUFFIX)
#define vsub CAT(vsub, SUFFIX)
#define vmul CAT(vmul, SUFFIX)
#define vhad CAT(vhad, SUFFIX)
#define vdot CAT(vdot, SUFFIX)
#define vcross CAT(vcross, SUFFIX)
#define vunit CAT(vunit, SUFFIX)
#define vmaxabs CAT(vmaxabs, SUFFIX)
#define vfrom CAT(vfrom, SUFFIX)
#define Sphere CAT(Sphere, SUFFIX)
#define Plane CAT(Plane, SUFFIX)
#define Tri CAT(Tri, SUFFIX)
#define Box CAT(Box, SUFFIX)
#define Group CAT(Group, SUFFIX)
#define Mat CAT(Mat, SUFFIX)
#define Lamp CAT(Lamp, SUFFIX)
#define World CAT(World, SUFFIX)
#define Hit CAT(Hit, SUFFIX)
#define Surface CAT(Surface, SUFFIX)
#define sphere_t CAT(sphere_t, SUFFIX)
#define plane_t CAT(plane_t, SUFFIX)
#define tri_t CAT(tri_t, SUFFIX)
#define box_hit CAT(box_hit, SUFFIX)
#define first_hit CAT(first_hit, SUFFIX)
#define surface_at CAT(surface_at, SUFFIX)
#define spawn CAT(spawn, SUFFIX)
#define lamp_at CAT(lamp_at, SUFFIX)
#define direct CAT(direct, SUFFIX)
#define refracted CAT(refracted, SUFFIX)
#define trace CAT(trace, SUFFIX)
#define add_triangles CAT(add_triangles, SUFFIX)
#define add_lamps CAT(add_lamps, SUFFIX)
#define build_world CAT(build_world, SUFFIX)
#define render CAT(render, SUFFIX)
#define grow_box CAT(grow_box, SUFFIX)
#define pad_box CAT(pad_box, SUFFIX)

#if defined(F32) && F32
#define SQRT sqrtf
#define POW powf
#define FLOOR floorf
#define COS cosf
#define ACOS acosf
#define TAN tanf
#define FABS fabsf
#define FMIN fminf
#define FMAX fmaxf
#else
#define SQRT sqrt
#define POW pow
#define FLOOR floor
#define COS cos
#define ACOS acos
#define TAN tan
#define FABS fabs
#define FMIN fmin
#define FMAX fmax
#endif
#define K(x) ((real)(x))

typedef struct {
    real x, y, z;
} vec;

static inline vec v3(real x, real y, real z) {
    vec r = {x, y, z};
    return r;
}
static inline vec vfrom(const double *p) { return v3((real)p[0], (real)p[1], (real)p[2]); }
static inline vec vadd(vec a, vec b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec vsub(vec a, vec b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec vmul(vec a, real k) { return v3(a.x * k, a.y * k, a.z * k); }
static inline vec vhad(vec a, vec b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline real vdot(vec a, vec b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline vec vcross(vec a, vec b) {
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline vec vunit(vec a) {
    real n = SQRT(vdot(a, a));
    return n > 0 ? vmul(a, K(1) / n) : a;
}
static inline real vmaxabs(vec a) { return FMAX(FABS(a.x), FMAX(FABS(a.y), FABS(a.z))); }

typedef struct {
    vec center;
    real radius, r2;
    int obj;
} Sphere;

typedef struct {
    vec point, n;
    int obj;
} Plane;

typedef struct {
    vec v0, e1, e2, n;   /* n: the face normal, unit((v1 - v0) x (v2 - v0)) */
    vec n0, n1, n2;      /* the vertex normals as given, when smooth */
    int smooth, obj;
} Tri;

typedef struct { /* a run of at most CHUNK consecutive faces of one mesh, in its box */
    vec lo, hi;
    int first, count;
} Box;

typedef struct { /* a mesh (or a lone triangle): its box and its runs of faces */
    vec lo, hi;
    int first, count;
} Group;

typedef struct {
    vec ka, kd, ks;
    real shininess, kr, kt, ior, cell;
    int other;
} Mat;

#ifndef TRACE_CORE_ONCE
#define TRACE_CORE_ONCE
enum { LAMP_DIRECTIONAL, LAMP_POINT, LAMP_SPOT };
#define CHUNK 16
#endif

typedef struct {
    int kind;
    vec color, position, direction; /* direction: the way the light travels, unit */
    real c, l, q;                   /* attenuation */
    real cos_out, cos_in, exponent; /* spot */
    real angle_out, angle_in;       /* spot, for a ramp in the angle */
} Lamp;

typedef struct {
    const Options *opt;
    const int *wrong; /* the mistakes, by M_ index */
    Sphere *spheres;
    Plane *planes;
    Tri *tris;
    Box *boxes;
    Group *groups;
    int nspheres, nplanes, ntris, nboxes, ngroups;
    Mat *mats;
    int *obj_mat, *obj_clear; /* per object: its material, and whether that material has k_t > 0 */
    Lamp *lamps;
    int nlamps;
    vec ambient, background;
    int depth_limit;
} World;

typedef struct {
    real t, u, v;
    int kind, index; /* kind: 0 sphere, 1 plane, 2 triangle */
} Hit;

/* ------------------------------------------------------------------ intersections */

/* The nearest root of |o + t d - c| = r in (tmin, tmax); d is a unit vector.  The discriminant is taken as
 * r^2 - |oc - b d|^2 and the roots as q and c/q, which keeps them exact for a huge sphere or a far ray. */
static int sphere_t(const Sphere *s, vec o, vec d, real tmin, real tmax, real *t) {
    vec oc = vsub(o, s->center);
    real b = vdot(oc, d);
    vec across = vsub(oc, vmul(d, b));
    real disc = s->r2 - vdot(across, across);
    if (disc < 0) return 0;
    real root = SQRT(disc);
    real c = vdot(oc, oc) - s->r2;
    real q = b > 0 ? -b - root : -b + root;
    real t0 = q, t1 = q != 0 ? c / q : q;
    if (t0 > t1) {
        real swap = t0;
        t0 = t1, t1 = swap;
    }
    if (t0 > tmin && t0 < tmax) return *t = t0, 1;
    if (t1 > tmin && t1 < tmax) return *t = t1, 1;
    return 0;
}

static int plane_t(const Plane *p, vec o, vec d, real tmin, real tmax, real *t) {
    real den = vdot(d, p->n);
    if (den == 0) return 0; /* a ray along the plane never hits it */
    real s = vdot(vsub(p->point, o), p->n) / den;
    if (s > tmin && s < tmax) return *t = s, 1;
    return 0;
}

/* Moller-Trumbore: t and the barycentric (u, v) of the hit (weights of v1 and v2). */
static int tri_t(const Tri *tr, vec o, vec d, real tmin, real tmax, real *t, real *u, real *v) {
    vec pv = vcross(d, tr->e2);
    real det = vdot(tr->e1, pv);
    if (det == 0) return 0;
    real inv = K(1) / det;
    vec tv = vsub(o, tr->v0);
    real a = vdot(tv, pv) * inv;
    if (a < 0 || a > 1) return 0;
    vec qv = vcross(tv, tr->e1);
    real b = vdot(d, qv) * inv;
    if (b < 0 || a + b > 1) return 0;
    real s = vdot(tr->e2, qv) * inv;
    if (s > tmin && s < tmax) {
        *t = s, *u = a, *v = b;
        return 1;
    }
    return 0;
}

/* Whether the ray meets the box before tmax (slabs; a zero direction component gives an infinite 1/d, and
 * fmin/fmax pass over the NaN of 0 * inf). */
static int box_hit(vec lo, vec hi, vec o, vec inv, real tmax) {
    real near = -INFINITY, far = tmax;
    real t1 = (lo.x - o.x) * inv.x, t2 = (hi.x - o.x) * inv.x;
    near = FMAX(near, FMIN(t1, t2)), far = FMIN(far, FMAX(t1, t2));
    t1 = (lo.y - o.y) * inv.y, t2 = (hi.y - o.y) * inv.y;
    near = FMAX(near, FMIN(t1, t2)), far = FMIN(far, FMAX(t1, t2));
    t1 = (lo.z - o.z) * inv.z, t2 = (hi.z - o.z) * inv.z;
    near = FMAX(near, FMIN(t1, t2)), far = FMIN(far, FMAX(t1, t2));
    return near <= far && far >= 0;
}

/* The first surface in (tmin, tmax), into *h; with `any`, the first found at all (a shadow ray), and with
 * `skip_clear`, objects whose material has k_t > 0 are not looked at. */
static int first_hit(const World *w, vec o, vec d, real tmin, real tmax, int any, int skip_clear, Hit *h) {
    int found = 0;
    real t, u = 0, v = 0;
    for (int k = 0; k < w->nspheres; k++) {
        if (skip_clear && w->obj_clear[w->spheres[k].obj]) continue;
        if (sphere_t(&w->spheres[k], o, d, tmin, tmax, &t)) {
            h->t = tmax = t, h->kind = 0, h->index = k, found = 1;
            if (any) return 1;
        }
    }
    for (int k = 0; k < w->nplanes; k++) {
        if (skip_clear && w->obj_clear[w->planes[k].obj]) continue;
        if (plane_t(&w->planes[k], o, d, tmin, tmax, &t)) {
            h->t = tmax = t, h->kind = 1, h->index = k, found = 1;
            if (any) return 1;
        }
    }
    vec inv = v3(K(1) / d.x, K(1) / d.y, K(1) / d.z);
    for (int g = 0; g < w->ngroups; g++) {
        const Group *grp = &w->groups[g];
        if (!box_hit(grp->lo, grp->hi, o, inv, tmax)) continue;
        for (int b = grp->first; b < grp->first + grp->count; b++) {
            const Box *box = &w->boxes[b];
            if (!box_hit(box->lo, box->hi, o, inv, tmax)) continue;
            for (int k = box->first; k < box->first + box->count; k++) {
                if (skip_clear && w->obj_clear[w->tris[k].obj]) continue;
                if (tri_t(&w->tris[k], o, d, tmin, tmax, &t, &u, &v)) {
                    h->t = tmax = t, h->u = u, h->v = v, h->kind = 2, h->index = k, found = 1;
                    if (any) return 1;
                }
            }
        }
    }
    return found;
}

/* ------------------------------------------------------------------ shading */

typedef struct {
    vec p, ng, n; /* the point, the geometric normal (as the format orients it), the shading normal */
    int obj, flat;
    vec p0; /* a point of the plane of a flat surface, for the checker */
} Surface;

static Surface surface_at(const World *w, vec o, vec d, const Hit *h) {
    Surface s;
    s.p = vadd(o, vmul(d, h->t));
    s.flat = h->kind != 0;
    if (h->kind == 0) {
        const Sphere *sp = &w->spheres[h->index];
        s.ng = vmul(vsub(s.p, sp->center), K(1) / sp->radius);
        s.n = s.ng, s.obj = sp->obj, s.p0 = sp->center;
    } else if (h->kind == 1) {
        const Plane *pl = &w->planes[h->index];
        s.ng = s.n = pl->n, s.obj = pl->obj, s.p0 = pl->point;
    } else {
        const Tri *tr = &w->tris[h->index];
        s.ng = s.n = tr->n, s.obj = tr->obj, s.p0 = tr->v0;
        if (tr->smooth) {
            vec blend = vadd(vadd(vmul(tr->n0, K(1) - h->u - h->v), vmul(tr->n1, h->u)), vmul(tr->n2, h->v));
            if (vdot(blend, blend) > 0) s.n = w->wrong[M_NOT_NORMALISED] ? blend : vunit(blend);
        }
    }
    return s;
}

/* Where a new ray along `dir` leaving the surface at P starts, and its t_min (see the header of ctracer.c). */
static vec spawn(const World *w, vec p, vec ng, vec dir, real travelled, real *tmin) {
    const Options *opt = w->opt;
    real eps;
    *tmin = 0;
    if (w->wrong[M_SHADOW_ACNE]) return p;
    if (opt->offset >= 0) {
        if (opt->along_ray) {
            *tmin = (real)opt->offset;
            return p;
        }
        eps = (real)opt->offset;
    } else {
        eps = REL * (vmaxabs(p) + travelled);
    }
    return vadd(p, vmul(ng, vdot(dir, ng) < 0 ? -eps : eps));
}

/* Towards the lamp from P (*l), its distance (*dist) and its intensity there (0: it gives nothing). */
static vec lamp_at(const World *w, const Lamp *lamp, vec p, vec *l, real *dist) {
    vec none = v3(0, 0, 0);
    if (lamp->kind == LAMP_DIRECTIONAL) {
        *l = vmul(lamp->direction, K(-1)), *dist = K(INFINITY);
        return lamp->color;
    }
    vec to = vsub(lamp->position, p);
    real d = SQRT(vdot(to, to));
    if (d == 0) return none; /* a point exactly at the light receives nothing from it */
    *l = vmul(to, K(1) / d), *dist = d;
    real den = lamp->c + lamp->l * d + lamp->q * d * d;
    if (den == 0) return none;
    real strength = K(1) / den;
    if (lamp->kind == LAMP_SPOT) {
        real s = -vdot(lamp->direction, *l);
        if (s < lamp->cos_out) return none;
        real ramp = 1;
        if (w->wrong[M_SPOT_RAMP_ANGLE] && lamp->angle_in < lamp->angle_out) {
            real angle = ACOS(FMIN(s, K(1)));
            ramp = (lamp->angle_out - angle) / (lamp->angle_out - lamp->angle_in);
            ramp = ramp > 1 ? 1 : ramp;
        } else if (s < lamp->cos_in) {
            ramp = (s - lamp->cos_out) / (lamp->cos_in - lamp->cos_out);
        }
        strength *= POW(s, lamp->exponent) * ramp;
    }
    return vmul(lamp->color, strength);
}

/* The Phong sum of every lamp at the surface, with shadow rays. */
static vec direct(const World *w, const Surface *s, const Mat *m, vec d, vec n, real travelled) {
    const int *wrong = w->wrong;
    vec colour = v3(0, 0, 0), view = vmul(d, K(-1));
    if (!wrong[M_NO_AMBIENT]) colour = vhad(wrong[M_AMBIENT_KD] ? m->kd : m->ka, w->ambient);
    for (int k = 0; k < w->nlamps; k++) {
        const Lamp *lamp = &w->lamps[k];
        vec l;
        real dist;
        vec in = lamp_at(w, lamp, s->p, &l, &dist);
        if (in.x == 0 && in.y == 0 && in.z == 0) continue;
        real nl = vdot(n, l);
        if (nl <= 0 && !wrong[M_SPEC_BEHIND]) continue;
        if (!wrong[M_NO_SHADOWS]) {
            real tmin, tmax = dist;
            vec from = spawn(w, s->p, s->ng, l, travelled, &tmin);
            if (lamp->kind != LAMP_DIRECTIONAL) tmax = dist - REL * (vmaxabs(lamp->position) + dist);
            Hit block;
            if (first_hit(w, from, l, tmin, tmax, 1, wrong[M_TRANSPARENT_NO_SHADOWS], &block)) continue;
        }
        real spec;
        if (wrong[M_BLINN]) {
            spec = vdot(n, vunit(vadd(l, view)));
        } else if (wrong[M_REFLECT_SIGN]) {
            spec = vdot(vsub(l, vmul(n, 2 * nl)), view);
        } else {
            spec = vdot(vsub(vmul(n, 2 * nl), l), view);
        }
        spec = spec > 0 ? POW(spec, m->shininess) : 0;
        vec lit = vmul(m->kd, nl > 0 ? nl : 0);
        if (!wrong[M_NO_SPECULAR]) lit = vadd(lit, vmul(m->ks, spec));
        colour = vadd(colour, vhad(in, lit));
    }
    return colour;
}

/* The refracted direction at a surface of geometric normal ng (TIR: the mirror direction). */
static vec refracted(const World *w, vec d, vec ng, real ior) {
    int enter = vdot(d, ng) < 0;
    vec facing = enter ? ng : vmul(ng, K(-1));
    real eta = enter ? K(1) / ior : ior;
    if (w->wrong[M_IOR_INVERTED]) eta = enter ? ior : K(1) / ior;
    real c = -vdot(d, facing);
    real k = 1 - eta * eta * (1 - c * c);
    if (k < 0) return vsub(d, vmul(facing, 2 * vdot(d, facing)));
    return vunit(vadd(vmul(d, eta), vmul(facing, eta * c - SQRT(k))));
}

static vec trace(const World *w, vec o, vec d, real tmin, int depth, real travelled) {
    Hit h;
    if (!first_hit(w, o, d, tmin, K(INFINITY), 0, 0, &h))
        return depth > 0 && w->wrong[M_MISS_BLACK] ? vmul(w->background, K(0)) : w->background;
    Surface s = surface_at(w, o, d, &h);
    const int *wrong = w->wrong;
    vec n = s.n;
    if (vdot(n, d) > 0 && !wrong[M_NOT_FLIPPED]) n = vmul(n, K(-1));
    const Mat *m = &w->mats[w->obj_mat[s.obj]];
    if (m->other >= 0 && !wrong[M_CHECKER_IGNORED]) {
        vec q = s.p;
        if (s.flat) q = vsub(q, vmul(s.ng, vdot(vsub(q, s.p0), s.ng)));
        long long cell = wrong[M_CHECKER_TRUNCATED] /* (long long) alone rounds toward 0 */
                             ? (long long)(q.x / m->cell) + (long long)(q.y / m->cell) + (long long)(q.z / m->cell)
                             : (long long)FLOOR(q.x / m->cell) + (long long)FLOOR(q.y / m->cell) +
                                   (long long)FLOOR(q.z / m->cell);
        if (cell & 1) m = &w->mats[m->other];
    }
    real far = travelled + h.t;
    vec colour = direct(w, &s, m, d, n, far);
    if (depth >= w->depth_limit) return colour;
    real start;
    if (m->kr > 0 && !wrong[M_NO_REFLECTION]) {
        vec r = vsub(d, vmul(n, 2 * vdot(d, n)));
        vec from = spawn(w, s.p, s.ng, r, far, &start);
        colour = vadd(colour, vmul(trace(w, from, r, start, depth + 1, far), m->kr));
    }
    if (m->kt > 0 && !wrong[M_NO_REFRACTION]) {
        vec t = refracted(w, d, s.ng, m->ior);
        vec from = spawn(w, s.p, s.ng, t, far, &start);
        colour = vadd(colour, vmul(trace(w, from, t, start, depth + 1, far), m->kt));
    }
    return colour;
}

/* ------------------------------------------------------------------ the scene in `real` */

static void grow_box(vec *lo, vec *hi, vec p) {
    lo->x = FMIN(lo->x, p.x), lo->y = FMIN(lo->y, p.y), lo->z = FMIN(lo->z, p.z);
    hi->x = FMAX(hi->x, p.x), hi->y = FMAX(hi->y, p.y), hi->z = FMAX(hi->z, p.z);
}

static void pad_box(vec *lo, vec *hi) {
    vec side = vsub(*hi, *lo);
    real pad = K(1e-3) * vmaxabs(side) + K(1e-5) * FMAX(vmaxabs(*lo), vmaxabs(*hi));
    *lo = vsub(*lo, v3(pad, pad, pad)), *hi = vadd(*hi, v3(pad, pad, pad));
}

/* The faces of triangle or mesh object `k` as triangles, in runs of CHUNK with their boxes, one group. */
static void add_triangles(World *w, const Object *o, int k) {
    Group *g = &w->groups[w->ngroups++];
    Box *box = NULL;
    g->first = w->nboxes, g->count = 0;
    for (int f = 0; f < o->nfaces; f++) {
        const int *idx = o->faces + 3 * f;
        vec a = vfrom(o->verts + 3 * idx[0]), b = vfrom(o->verts + 3 * idx[1]), c = vfrom(o->verts + 3 * idx[2]);
        vec cross = vcross(vsub(b, a), vsub(c, a));
        if (vdot(cross, cross) == 0) continue; /* a face of zero area is never hit */
        if (!box || box->count == CHUNK) {
            box = &w->boxes[w->nboxes++];
            box->first = w->ntris, box->count = 0;
            box->lo = v3(K(INFINITY), K(INFINITY), K(INFINITY)), box->hi = vmul(box->lo, K(-1));
            g->count++;
        }
        Tri *t = &w->tris[w->ntris++];
        t->v0 = a, t->e1 = vsub(b, a), t->e2 = vsub(c, a), t->n = vunit(cross), t->obj = k;
        t->smooth = o->normals != NULL;
        if (t->smooth) {
            t->n0 = vfrom(o->normals + 3 * idx[0]);
            t->n1 = vfrom(o->normals + 3 * idx[1]);
            t->n2 = vfrom(o->normals + 3 * idx[2]);
        }
        box->count++;
        grow_box(&box->lo, &box->hi, a), grow_box(&box->lo, &box->hi, b), grow_box(&box->lo, &box->hi, c);
    }
    g->lo = v3(K(INFINITY), K(INFINITY), K(INFINITY)), g->hi = vmul(g->lo, K(-1));
    for (int b = g->first; b < g->first + g->count; b++) {
        pad_box(&w->boxes[b].lo, &w->boxes[b].hi);
        grow_box(&g->lo, &g->hi, w->boxes[b].lo), grow_box(&g->lo, &g->hi, w->boxes[b].hi);
    }
}

static void add_lamps(World *w, const Light *light) {
    const int *wrong = w->wrong;
    Lamp lamp;
    memset(&lamp, 0, sizeof lamp);
    lamp.color = vfrom(light->color);
    lamp.c = (real)light->attenuation[0], lamp.l = (real)light->attenuation[1], lamp.q = (real)light->attenuation[2];
    if (wrong[M_NO_ATTEN]) lamp.c = 1, lamp.l = 0, lamp.q = 0;
    if (light->type == L_AMBIENT) {
        w->ambient = vadd(w->ambient, lamp.color);
    } else if (light->type == L_DIRECTIONAL) {
        lamp.kind = LAMP_DIRECTIONAL, lamp.direction = vunit(vfrom(light->direction));
        w->lamps[w->nlamps++] = lamp;
    } else if (light->type == L_POINT || light->type == L_SPOT) {
        lamp.kind = light->type == L_POINT ? LAMP_POINT : LAMP_SPOT;
        lamp.position = vfrom(light->position), lamp.direction = vunit(vfrom(light->direction));
        real per_degree = wrong[M_SPOT_RADIANS] ? K(1) : K(3.14159265358979323846) / K(180);
        lamp.angle_out = (real)light->cutoff * per_degree, lamp.angle_in = (real)light->inner * per_degree;
        lamp.cos_out = COS(lamp.angle_out), lamp.cos_in = COS(lamp.angle_in);
        lamp.exponent = (real)light->exponent;
        w->lamps[w->nlamps++] = lamp;
    } else {
        vec corner = vfrom(light->corner), eu = vfrom(light->eu), ev = vfrom(light->ev);
        lamp.kind = LAMP_POINT;
        if (!wrong[M_AREA_NOT_DIVIDED]) lamp.color = vmul(lamp.color, K(1) / (real)(light->nu * light->nv));
        for (int i = 0; i < light->nu; i++)
            for (int j = 0; j < light->nv; j++) {
                real h = wrong[M_AREA_AT_CORNERS] ? K(0) : K(0.5); /* a cell's corner, not its centre */
                real a = ((real)i + h) / (real)light->nu, b = ((real)j + h) / (real)light->nv;
                lamp.position = vadd(corner, vadd(vmul(eu, a), vmul(ev, b)));
                w->lamps[w->nlamps++] = lamp;
            }
    }
}

static void build_world(World *w, const Scene *sc, const Options *opt) {
    memset(w, 0, sizeof *w);
    w->opt = opt, w->wrong = opt->mistake;
    int faces = 0, groups = 0, lamps = 0;
    for (int k = 0; k < sc->nobj; k++)
        if (sc->objs[k].type == O_TRIANGLE || sc->objs[k].type == O_MESH) faces += sc->objs[k].nfaces, groups++;
    for (int k = 0; k < sc->nlight; k++)
        lamps += sc->lights[k].type == L_AREA ? sc->lights[k].nu * sc->lights[k].nv : 1;
    w->spheres = grow(NULL, sizeof(Sphere) * (size_t)sc->nobj);
    w->planes = grow(NULL, sizeof(Plane) * (size_t)sc->nobj);
    w->tris = grow(NULL, sizeof(Tri) * (size_t)faces);
    w->boxes = grow(NULL, sizeof(Box) * (size_t)faces);
    w->groups = grow(NULL, sizeof(Group) * (size_t)groups);
    w->lamps = grow(NULL, sizeof(Lamp) * (size_t)lamps);
    w->obj_mat = grow(NULL, sizeof(int) * (size_t)sc->nobj);
    w->obj_clear = grow(NULL, sizeof(int) * (size_t)sc->nobj);
    w->mats = grow(NULL, sizeof(Mat) * (size_t)sc->nmat);
    for (int k = 0; k < sc->nmat; k++) {
        const Material *m = &sc->mats[k];
        Mat *r = &w->mats[k];
        r->ka = vfrom(m->ka), r->kd = vfrom(m->kd), r->ks = vfrom(m->ks);
        r->shininess = (real)m->shininess, r->kr = (real)m->kr, r->kt = (real)m->kt, r->ior = (real)m->ior;
        r->cell = (real)m->cell, r->other = m->other;
    }
    for (int k = 0; k < sc->nobj; k++) {
        const Object *o = &sc->objs[k];
        w->obj_mat[k] = o->material, w->obj_clear[k] = sc->mats[o->material].kt > 0;
        if (o->type == O_SPHERE) {
            Sphere *s = &w->spheres[w->nspheres++];
            s->center = vfrom(o->center), s->radius = (real)o->radius, s->r2 = s->radius * s->radius, s->obj = k;
        } else if (o->type == O_PLANE) {
            Plane *p = &w->planes[w->nplanes++];
            p->point = vfrom(o->point), p->n = vunit(vfrom(o->normal)), p->obj = k;
        } else {
            add_triangles(w, o, k);
        }
    }
    for (int k = 0; k < sc->nlight; k++) add_lamps(w, &sc->lights[k]);
    w->background = vfrom(sc->background);
    w->depth_limit = sc->max_depth + opt->mistake[M_DEPTH_PLUS] - opt->mistake[M_DEPTH_MINUS];
}

static void render(const Scene *sc, const Options *opt, unsigned char *rgb) {
    World w;
    build_world(&w, sc, opt);
    const int *wrong = opt->mistake;
    int width = sc->width, height = sc->height, n = wrong[M_SAMPLES_IGNORED] ? 1 : sc->samples;
    vec eye = vfrom(sc->eye), up = vfrom(sc->up);
    vec f = vunit(vsub(vfrom(sc->look_at), eye));
    vec r = wrong[M_LEFT_HANDED] ? vunit(vcross(up, f)) : vunit(vcross(f, up));
    vec u = wrong[M_LEFT_HANDED] ? vcross(f, r) : wrong[M_UP_AS_GIVEN] ? vunit(up) : vcross(r, f);
    real h = sc->ortho ? (real)sc->view_height / 2 : TAN((real)sc->fov * K(3.14159265358979323846) / K(360));
    real across = h * (real)width / (real)height, down = h;
    if (wrong[M_HFOV]) across = h, down = h * (real)height / (real)width;
    if (wrong[M_ASPECT_INVERTED]) across = h * (real)height / (real)width;
    real centre = wrong[M_NO_HALF] ? K(0) : K(0.5);
    for (int j = 0; j < height; j++)
        for (int i = 0; i < width; i++) {
            vec sum = v3(0, 0, 0);
            for (int b = 0; b < n; b++)
                for (int a = 0; a < n; a++) {
                    real sx = ((real)i + ((real)a + centre) / (real)n) / (real)width;
                    real sy = ((real)j + ((real)b + centre) / (real)n) / (real)height;
                    real x = (2 * sx - 1) * across;
                    real y = wrong[M_IMAGE_FLIPPED] ? (2 * sy - 1) * down : (1 - 2 * sy) * down;
                    vec o = eye, d;
                    if (sc->ortho) {
                        o = vadd(eye, vadd(vmul(r, x), vmul(u, y)));
                        d = f;
                    } else {
                        d = vunit(vadd(f, vadd(vmul(r, x), vmul(u, y))));
                    }
                    sum = vadd(sum, trace(&w, o, d, 0, 0, 0));
                }
            real v[3] = {sum.x, sum.y, sum.z};
            unsigned char *px = rgb + 3 * ((size_t)j * (size_t)width + (size_t)i);
            for (int c = 0; c < 3; c++) {
                real x = v[c] / (real)(n * n);
                if (wrong[M_NOT_CLAMPED]) {
                    if (wrong[M_GAMMA]) x = POW(x, K(1) / K(2.2));
                    if (x != x) x = 0;
                    px[c] = (unsigned char)(int)(255 * x + K(0.5));
                    continue;
                }
                x = x > 0 ? (x < 1 ? x : 1) : 0; /* (a NaN, from a pow of a negative, is 0) */
                if (wrong[M_GAMMA]) x = POW(x, K(1) / K(2.2));
                px[c] = (unsigned char)FLOOR(255 * x + K(0.5));
            }
        }
}

#undef vec
#undef v3
#undef vadd
#undef vsub
#undef vmul
#undef vhad
#undef vdot
#undef vcross
#undef vunit
#undef vmaxabs
#undef vfrom
#undef Sphere
#undef Plane
#undef Tri
#undef Box
#undef Group
#undef Mat
#undef Lamp
#undef World
#undef Hit
#undef Surface
#undef sphere_t
#undef plane_t
#undef tri_t
#undef box_hit
#undef first_hit
#undef surface_at
#undef spawn
#undef lamp_at
#undef direct
#undef refracted
#undef trace
#undef add_triangles
#undef add_lamps
#undef build_world
#undef render
#undef grow_box
#undef pad_box
#undef FMIN
#undef FMAX
#undef SQRT
#undef POW
#undef FLOOR
#undef COS
#undef ACOS
#undef TAN
#undef FABS
#undef K
