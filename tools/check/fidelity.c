/* i2m-check: fidelity of a mesh to its label image.  Everything is computed in the image's
 * grid frame (mm, axis-aligned; mesh vertices mapped with i2m_image_world_to_grid).
 *   image interfaces: the voxel faces between two different labels, including the faces
 *     between a non-zero voxel and the outside of the image;
 *   mesh -> image: every interface triangle sampled on a barycentric grid of spacing
 *     <= min voxel spacing / 2 (vertices and edge midpoints included), each sample's exact
 *     distance to the nearest image interface face (point-to-square);
 *   image -> mesh: every image interface face, the largest of the exact distances from its
 *     centre and its four corners to the nearest mesh interface triangle;
 *   per-label volumes and 6-connected components of the image (run-length union-find) and
 *     of the mesh (tetrahedra of one label sharing faces).
 * Nearest queries use a uniform grid of buckets, searched in a box of growing radius that
 * starts from an upper bound (the previous query's distance plus the step between the two
 * query points), so that each query looks at a few buckets only. */
#include "check.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef double (*dist_fn)(const void *ctx, int64_t i, const double p[3]);

static inline double gap(double lo, double hi, double x)
{
  return x < lo ? lo - x : x > hi ? x - hi : 0.0;
}

/* The items one thread's search has measured for the current point (mark[i] == query): an
 * item that spans several cells, or a cell met again when the box grows, is measured once. */
typedef struct {
  uint32_t *mark; /* [n], or NULL: no marks (every item met is measured) */
  uint32_t query;
  int64_t n;
} seen_t;

static void seen_begin(seen_t *s, const ck_grid_t *g)
{
  s->query = 0;
  s->n = g->nitems ? g->nitems : 1;
  if (i2m_calloc((size_t)s->n, sizeof *s->mark, &s->mark) != I2M_OK) s->mark = NULL; /* (then no marks) */
}

/* Whether item i is measured already for this point (and marks it). */
static int seen_again(seen_t *s, int64_t i)
{
  if (!s || !s->mark) return 0;
  if (s->mark[i] == s->query) return 1;
  s->mark[i] = s->query;
  return 0;
}

static void seen_next_point(seen_t *s)
{
  if (!s || !s->mark) return;
  if (++s->query == 0) { /* (wrapped: the old marks could pass for the new point's) */
    memset(s->mark, 0, (size_t)s->n * sizeof *s->mark);
    s->query = 1;
  }
}

/* Exact distance from p to the nearest item, given an upper bound ub (INFINITY if none).
 * The searched box grows from one cell by doubling until it holds the answer; ub only
 * prunes (a far ub never makes the box large).  seen: the thread's marks, or NULL. */
static double grid_nearest(const ck_grid_t *g, const double p[3], double ub, dist_fn dist,
                           const void *ctx, int64_t *hint, seen_t *seen)
{
  if (g->nitems == 0) return INFINITY;
  seen_next_point(seen);
  double best2 = isfinite(ub) ? ub * ub * (1 + 1e-12) + 1e-300 : INFINITY;
  if (hint && *hint >= 0) { /* the previous query's nearest item: usually a tight bound */
    seen_again(seen, *hint);
    double d2 = dist(ctx, *hint, p);
    if (d2 < best2) {
      best2 = d2;
      ub = sqrt(d2);
    }
  }
  double r = g->h[0] > g->h[1] ? g->h[0] : g->h[1];
  r = r > g->h[2] ? r : g->h[2];
  if (ub < r) r = ub * (1 + 1e-12) + 1e-300; /* a tight bound: one pass */
  for (;;) {
    int64_t c0[3], c1[3];
    int all = 1;
    for (int a = 0; a < 3; a++) {
      c0[a] = ck_grid_cell(g, a, p[a] - r);
      c1[a] = ck_grid_cell(g, a, p[a] + r);
      all &= p[a] - r <= g->lo[a] && p[a] + r >= g->lo[a] + (double)g->n[a] * g->h[a];
    }
    for (int64_t z = c0[2]; z <= c1[2]; z++) {
      double dz = gap(g->lo[2] + (double)z * g->h[2], g->lo[2] + (double)(z + 1) * g->h[2], p[2]);
      if (dz * dz >= best2) continue;
      for (int64_t y = c0[1]; y <= c1[1]; y++) {
        double dy = gap(g->lo[1] + (double)y * g->h[1], g->lo[1] + (double)(y + 1) * g->h[1], p[1]);
        double dzy = dz * dz + dy * dy;
        if (dzy >= best2) continue;
        const int64_t *st = g->start + (z * g->n[1] + y) * g->n[0];
        for (int64_t x = c0[0]; x <= c1[0]; x++) {
          if (st[x] == st[x + 1]) continue;
          double dx = gap(g->lo[0] + (double)x * g->h[0], g->lo[0] + (double)(x + 1) * g->h[0], p[0]);
          /* the grid covers every item, so the cell box bounds its items' distances */
          if (dzy + dx * dx >= best2) continue;
          for (int64_t k = st[x]; k < st[x + 1]; k++) {
            if (seen_again(seen, g->item[k])) continue;
            double d2 = dist(ctx, g->item[k], p);
            if (d2 < best2) {
              best2 = d2;
              if (hint) *hint = g->item[k];
            }
          }
        }
      }
    }
    if (best2 <= r * r || all) break;
    r *= 2;
  }
  return sqrt(best2);
}

/* ---- image interface faces ---- */
typedef struct {
  int32_t c[3]; /* lower voxel (may be -1 on the axis) */
  int32_t axis;
} vface_t;

typedef struct {
  const i2m_image_t *img;
  const vface_t *f;
  double *box; /* owned: [nf][6] lo, hi of every face */
} fctx_t;

static void face_box(const fctx_t *x, int64_t i, double lo[3], double hi[3])
{
  const vface_t *f = x->f + i;
  for (int a = 0; a < 3; a++) {
    double s = x->img->spacing[a];
    if (a == f->axis) {
      lo[a] = hi[a] = (f->c[a] + 0.5) * s;
    } else {
      lo[a] = (f->c[a] - 0.5) * s;
      hi[a] = (f->c[a] + 0.5) * s;
    }
  }
}

static void face_bbox(const void *ctx, int64_t i, double lo[3], double hi[3])
{
  face_box(ctx, i, lo, hi);
}

static double face_dist2(const void *ctx, int64_t i, const double p[3])
{
  const double *b = ((const fctx_t *)ctx)->box + 6 * i;
  double dx = gap(b[0], b[3], p[0]), dy = gap(b[1], b[4], p[1]), dz = gap(b[2], b[5], p[2]);
  return dx * dx + dy * dy + dz * dz;
}

/* The interface faces whose lower voxel lies in slice k (-1 .. n[2]-1), in (j, i, axis) order,
 * into out when not NULL; returns their number. */
static int64_t slice_faces(const i2m_image_t *img, int64_t k, vface_t *out)
{
  int64_t n = 0;
  for (int64_t j = -1; j < img->n[1]; j++)
    for (int64_t i = -1; i < img->n[0]; i++) {
      const int l0 = i2m_image_label_voxel(img, i, j, k);
      const int64_t nb[3][3] = {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}};
      for (int a = 0; a < 3; a++) {
        /* the lower voxel may be outside on this axis only */
        if ((a != 0 && i < 0) || (a != 1 && j < 0) || (a != 2 && k < 0)) continue;
        if (l0 == i2m_image_label_voxel(img, nb[a][0], nb[a][1], nb[a][2])) continue;
        if (out) out[n] = (vface_t){{(int32_t)i, (int32_t)j, (int32_t)k}, a};
        n++;
      }
    }
  return n;
}

/* Every interface face of the image, slice by slice: a count per slice, then each slice
 * fills its own range (threads; the order is that of one pass). */
static i2m_err_t image_faces(const i2m_image_t *img, vface_t **out, int64_t *nout)
{
  const int64_t ns = img->n[2] + 1; /* slices k = -1 .. n[2]-1 */
  int64_t *off = NULL;
  *out = NULL;
  *nout = 0;
  I2M_CALL(i2m_calloc((size_t)ns + 1, sizeof *off, &off));
  ck_progress_t pr;
  ck_progress_begin(&pr, "fidelity, image interface faces (2 passes)", "slices", 2 * ns);
  CK_OMP("omp parallel for schedule(dynamic, 2)")
  for (int64_t s = 0; s < ns; s++) {
    off[s + 1] = slice_faces(img, s - 1, NULL);
    ck_progress_add(&pr, 1);
  }
  for (int64_t s = 0; s < ns; s++) off[s + 1] += off[s];
  i2m_err_t err = i2m_malloc((size_t)(off[ns] ? off[ns] : 1), sizeof **out, out);
  if (err == I2M_OK) {
    CK_OMP("omp parallel for schedule(dynamic, 2)")
    for (int64_t s = 0; s < ns; s++) {
      slice_faces(img, s - 1, *out + off[s]);
      ck_progress_add(&pr, 1);
    }
    *nout = off[ns];
  }
  ck_progress_end(&pr);
  i2m_free(&off);
  return err;
}

/* ---- mesh interface triangles in the grid frame ---- */
typedef struct {
  const double *g;   /* [nv][3] grid-frame vertices */
  const int32_t *v;  /* [n][3] */
} tctx_t;

static void tri_bbox(const void *ctx, int64_t i, double lo[3], double hi[3])
{
  const tctx_t *t = ctx;
  for (int a = 0; a < 3; a++) {
    lo[a] = INFINITY;
    hi[a] = -INFINITY;
    for (int j = 0; j < 3; j++) {
      double x = t->g[3 * t->v[3 * i + j] + a];
      lo[a] = fmin(lo[a], x);
      hi[a] = fmax(hi[a], x);
    }
  }
}

static double tri_dist2(const void *ctx, int64_t i, const double p[3])
{
  const tctx_t *t = ctx;
  const int32_t *v = t->v + 3 * i;
  return ck_dist2_point_triangle(p, t->g + 3 * v[0], t->g + 3 * v[1], t->g + 3 * v[2]);
}

/* Number of samples of a triangle: (n+1)(n+2)/2 with n even and n * spacing >= longest edge. */
static int64_t tri_divisions(const double *a, const double *b, const double *c, double h)
{
  double l = 0;
  const double *p[3] = {a, b, c};
  for (int i = 0; i < 3; i++) {
    const double *x = p[i], *y = p[(i + 1) % 3];
    l = fmax(l, sqrt(i2m_sq(x[0] - y[0]) + i2m_sq(x[1] - y[1]) + i2m_sq(x[2] - y[2])));
  }
  /* A huge triangle (far beyond any mesh that overlays its image: 256 samples along an edge
   * are 128 voxels) gets at most 33,153 samples, so a stray vertex costs a fraction of a
   * second, not minutes. */
  double q = ceil(l / h);
  int64_t n = q >= 2.0 ? (q < 256.0 ? (int64_t)q : 256) : 2;
  if (n % 2) n++;
  return n;
}

static void tri_sample(const double *a, const double *b, const double *c, int64_t n, int64_t s,
                       double p[3])
{
  /* sample s enumerates (i, j), i + j <= n, row by row */
  int64_t i = 0, row = n + 1;
  while (s >= row) {
    s -= row;
    i++;
    row--;
  }
  double u = (double)i / (double)n, w = (double)s / (double)n;
  for (int k = 0; k < 3; k++) p[k] = a[k] + u * (b[k] - a[k]) + w * (c[k] - a[k]);
}

/* Both directed distance sets with the surface area each sample stands for, pooled for the
 * two-sided percentile.  Percentiles weigh every sample by its area (one side's or both). */
typedef struct {
  float *d[2], *w[2];
  int64_t n[2];
} pooled_t;

static double tri_area(const double *a, const double *b, const double *c)
{
  double u[3], v[3];
  for (int k = 0; k < 3; k++) {
    u[k] = b[k] - a[k];
    v[k] = c[k] - a[k];
  }
  double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2], z = u[0] * v[1] - u[1] * v[0];
  return 0.5 * sqrt(x * x + y * y + z * z);
}

/* The q-quantile of the area-weighted distances of sides s0..s1 of the pool (a histogram of
 * 2^20 bins up to the largest distance: exact to max / 2^20).  The arrays are only read, so
 * every distance stays paired with its weight. */
static double weighted_quantile(const pooled_t *p, int s0, int s1, double q)
{
  double dmax = 0, wsum = 0;
  for (int s = s0; s <= s1; s++)
    for (int64_t i = 0; i < p->n[s]; i++) {
      dmax = fmax(dmax, p->d[s][i]);
      wsum += p->w[s][i];
    }
  if (!(dmax > 0) || !(wsum > 0)) return 0.0;
  enum { NB = 1 << 20 };
  double *h = calloc(NB, sizeof *h);
  if (!h) return NAN;
  for (int s = s0; s <= s1; s++)
    for (int64_t i = 0; i < p->n[s]; i++) {
      int64_t b = (int64_t)((double)p->d[s][i] / dmax * (NB - 1));
      h[b < 0 ? 0 : b >= NB ? NB - 1 : b] += p->w[s][i];
    }
  double acc = 0, x = dmax;
  for (int64_t b = 0; b < NB; b++) {
    acc += h[b];
    if (acc >= q * wsum) {
      x = (double)(b + 1) / (NB - 1) * dmax;
      break;
    }
  }
  free(h);
  return fmin(x, dmax);
}

/* Finishes one side's summary and hands its samples over to the pool (side 0: mesh to
 * image, 1: image to mesh); *d and *w are then owned by the pool. */
static void pooled_take(pooled_t *p, int side, float **d, float **w, int64_t ns, double sum, ck_dist_t *out)
{
  p->d[side] = *d;
  p->w[side] = *w;
  p->n[side] = ns;
  out->count = ns;
  out->mean = ns ? sum / (double)ns : 0.0;
  out->p99 = weighted_quantile(p, side, side, 0.99);
  *d = NULL;
  *w = NULL;
}

static void pooled_free(pooled_t *p)
{
  for (int s = 0; s < 2; s++) {
    i2m_free(&p->d[s]);
    i2m_free(&p->w[s]);
  }
}

/* mesh -> image */
static i2m_err_t mesh_to_image(const tctx_t *tc, int64_t ntri, const ck_grid_t *fg, const fctx_t *fc,
                               double h, const i2m_image_t *img, ck_fidelity_t *f, pooled_t *pool)
{
  int64_t *off = NULL, *arg = NULL;
  float *d = NULL, *w = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL(i2m_malloc((size_t)ntri + 1, sizeof *off, &off));
  off[0] = 0;
  for (int64_t t = 0; t < ntri; t++) {
    const int32_t *v = tc->v + 3 * t;
    int64_t n = tri_divisions(tc->g + 3 * v[0], tc->g + 3 * v[1], tc->g + 3 * v[2], h);
    off[t + 1] = off[t] + (n + 1) * (n + 2) / 2;
  }
  int64_t ns = off[ntri];
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)ns, sizeof *d, &d));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)ns, sizeof *w, &w));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)ntri, sizeof *arg, &arg));
  for (int64_t t = 0; t < ntri; t++) { /* each sample stands for an equal share of its triangle */
    const int32_t *v = tc->v + 3 * t;
    float share = (float)(tri_area(tc->g + 3 * v[0], tc->g + 3 * v[1], tc->g + 3 * v[2]) / (double)(off[t + 1] - off[t]));
    for (int64_t s = off[t]; s < off[t + 1]; s++) w[s] = share;
  }
  double sum = 0.0;
  ck_progress_t pr;
  ck_progress_begin(&pr, "fidelity, mesh->image distances", "samples", ns);
  CK_OMP("omp parallel for schedule(dynamic, 64) reduction(+ : sum)")
  for (int64_t t = 0; t < ntri; t++) {
    const int32_t *v = tc->v + 3 * t;
    const double *a = tc->g + 3 * v[0], *b = tc->g + 3 * v[1], *c = tc->g + 3 * v[2];
    int64_t n = tri_divisions(a, b, c, h), cnt = off[t + 1] - off[t];
    if (t % 64 == 0) ck_progress_add(&pr, off[t + 64 < ntri ? t + 64 : ntri] - off[t]); /* per chunk, at its start */
    double prev[3] = {0, 0, 0}, pd = INFINITY, best = -1;
    int64_t hint = -1;
    arg[t] = 0;
    for (int64_t s = 0; s < cnt; s++) {
      double p[3];
      tri_sample(a, b, c, n, s, p);
      double ub = isfinite(pd) ? pd + sqrt(i2m_sq(p[0] - prev[0]) + i2m_sq(p[1] - prev[1]) +
                                           i2m_sq(p[2] - prev[2]))
                               : INFINITY;
      pd = grid_nearest(fg, p, ub, face_dist2, fc, &hint, NULL); /* (faces rarely span cells: no marks) */
      memcpy(prev, p, sizeof prev);
      d[off[t] + s] = (float)pd;
      sum += pd;
      if (pd > best) {
        best = pd;
        arg[t] = s;
      }
    }
  }
  ck_progress_end(&pr);
  int64_t wt = -1;
  double wmax = -1;
  for (int64_t t = 0; t < ntri; t++)
    if (d[off[t] + arg[t]] > wmax) {
      wmax = d[off[t] + arg[t]];
      wt = t;
    }
  f->mesh_to_image.max = ntri ? wmax : 0.0;
  if (wt >= 0) {
    const int32_t *v = tc->v + 3 * wt;
    double p[3];
    int64_t n = tri_divisions(tc->g + 3 * v[0], tc->g + 3 * v[1], tc->g + 3 * v[2], h);
    tri_sample(tc->g + 3 * v[0], tc->g + 3 * v[1], tc->g + 3 * v[2], n, arg[wt], p);
    f->mesh_to_image.max = grid_nearest(fg, p, INFINITY, face_dist2, fc, NULL, NULL);
    i2m_image_grid_to_world(img, p, f->mesh_to_image.where);
  }
  f->mesh_samples = ns;
  pooled_take(pool, 0, &d, &w, ns, sum, &f->mesh_to_image);
out:
  i2m_free(&off);
  i2m_free(&arg);
  i2m_free(&d);
  i2m_free(&w);
  return err;
}

/* Points of an image face: nine sample points (centres of a 3 x 3 split, each standing for
 * a ninth of the face) then the four corners (for the maximum only). */
#define FACE_SAMPLES 9
#define FACE_CENTRE 4 /* (the sample at the face's centre) */
#define FACE_POINTS 13
static void face_points(const i2m_image_t *img, const vface_t *f, double p[FACE_POINTS][3])
{
  int a = f->axis, b = (a + 1) % 3, c = (a + 2) % 3;
  double x[3];
  for (int k = 0; k < 3; k++) x[k] = f->c[k] * img->spacing[k];
  x[a] += 0.5 * img->spacing[a];
  static const double t[3] = {-1.0 / 3.0, 0.0, 1.0 / 3.0};
  static const double sb[4] = {-0.5, 0.5, -0.5, 0.5}, sc[4] = {-0.5, -0.5, 0.5, 0.5};
  for (int q = 0; q < FACE_POINTS; q++) {
    memcpy(p[q], x, sizeof x);
    double ub = q < FACE_SAMPLES ? t[q % 3] : sb[q - FACE_SAMPLES];
    double uc = q < FACE_SAMPLES ? t[q / 3] : sc[q - FACE_SAMPLES];
    p[q][b] += ub * img->spacing[b];
    p[q][c] += uc * img->spacing[c];
  }
}

#define CK_CHUNK 1024

/* Image -> mesh for image faces [i0, i1) (one chunk, searched in order: each point's nearest
 * triangle bounds the next one's search); returns the sum of the samples' distances. */
static double image_chunk(const vface_t *faces, int64_t i0, int64_t i1, const ck_grid_t *tg, const tctx_t *tc,
                          const i2m_image_t *img, seen_t *sn, float *d, float *w, float *fmaxd)
{
  double prev[3] = {0, 0, 0}, pd = INFINITY, largest = 0.0, sum = 0.0; /* largest: the chunk's so far */
  int64_t hint = -1;
  for (int64_t i = i0; i < i1; i++) {
    double p[FACE_POINTS][3], m = 0.0, centre = 0.0; /* centre: its centre's distance */
    int ax = faces[i].axis;
    const double sb = img->spacing[(ax + 1) % 3], sc = img->spacing[(ax + 2) % 3];
    float share = (float)(sb * sc / FACE_SAMPLES);
    face_points(img, faces + i, p);
    /* The corners count for the maximum only, and lie within half the face's diagonal of
     * its centre: when the centre's distance plus that cannot beat the largest found, they
     * cannot raise the maximum (the face's own is then a lower bound, which the search for
     * the worst face below may take: a face it picks is recomputed whole). */
    for (int q = 0; q < FACE_POINTS; q++) {
      if (q == FACE_SAMPLES && centre + 0.5 * sqrt(sb * sb + sc * sc) <= largest) break;
      double ub = isfinite(pd) ? pd + sqrt(i2m_sq(p[q][0] - prev[0]) + i2m_sq(p[q][1] - prev[1]) +
                                           i2m_sq(p[q][2] - prev[2]))
                               : INFINITY;
      pd = grid_nearest(tg, p[q], ub, tri_dist2, tc, &hint, sn);
      memcpy(prev, p[q], sizeof prev);
      m = fmax(m, pd);
      if (q == FACE_CENTRE) centre = pd;
      if (q < FACE_SAMPLES) {
        d[i * FACE_SAMPLES + q] = (float)pd;
        w[i * FACE_SAMPLES + q] = share;
        sum += pd;
      }
    }
    fmaxd[i] = (float)m;
    largest = m > largest ? m : largest;
  }
  return sum;
}

/* Image -> mesh: every face's nine samples go to the distribution (each weighing a ninth of
 * the face's area); its corners count for the maximum. */
static i2m_err_t image_to_mesh(const vface_t *faces, int64_t nf, const ck_grid_t *tg,
                               const tctx_t *tc, const i2m_image_t *img, ck_fidelity_t *f,
                               int64_t *worst, pooled_t *pool)
{
  float *d = NULL, *w = NULL, *fmaxd = NULL;
  int64_t ns = nf * FACE_SAMPLES;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, fail, i2m_malloc((size_t)ns, sizeof *d, &d));
  I2M_CALL_GOTO(err, fail, i2m_malloc((size_t)ns, sizeof *w, &w));
  I2M_CALL_GOTO(err, fail, i2m_malloc((size_t)nf, sizeof *fmaxd, &fmaxd));
  double sum = 0.0;
  int64_t nchunk = (nf + CK_CHUNK - 1) / CK_CHUNK;
  ck_progress_t pr;
  ck_progress_begin(&pr, "fidelity, image->mesh distances", "image faces", nf);
  CK_OMP("omp parallel reduction(+ : sum)")
  {
    seen_t sn;
    seen_begin(&sn, tg);
    CK_OMP("omp for schedule(dynamic, 4)")
    for (int64_t ch = 0; ch < nchunk; ch++) {
      const int64_t i0 = ch * CK_CHUNK, i1 = i0 + CK_CHUNK < nf ? i0 + CK_CHUNK : nf;
      ck_progress_add(&pr, i1 - i0); /* (counted as the chunk starts) */
      sum += image_chunk(faces, i0, i1, tg, tc, img, &sn, d, w, fmaxd);
    }
    i2m_free(&sn.mark);
  }
  ck_progress_end(&pr);
  *worst = -1;
  double wmax = -1;
  for (int64_t i = 0; i < nf; i++)
    if (fmaxd[i] > wmax) {
      wmax = fmaxd[i];
      *worst = i;
    }
  if (*worst >= 0) { /* recompute the worst exactly (in double) and locate it */
    double p[FACE_POINTS][3], m = -1;
    int qm = 0;
    face_points(img, faces + *worst, p);
    for (int q = 0; q < FACE_POINTS; q++) {
      double x = grid_nearest(tg, p[q], INFINITY, tri_dist2, tc, NULL, NULL);
      if (x > m) {
        m = x;
        qm = q;
      }
    }
    f->image_to_mesh.max = m;
    i2m_image_grid_to_world(img, p[qm], f->image_to_mesh.where);
  }
  f->image_faces = nf;
  pooled_take(pool, 1, &d, &w, ns, sum, &f->image_to_mesh);
fail:
  i2m_free(&d);
  i2m_free(&w);
  i2m_free(&fmaxd);
  return err;
}

/* Component size of voxel (i,j,k); 0 outside the image. */
static int64_t voxel_component(const i2m_components_t *r, int64_t i, int64_t j, int64_t k)
{
  const int64_t root = i2m_components_find(r, i, j, k);
  return root < 0 ? 0 : r->size[root];
}

i2m_err_t ck_mesh_components(const ck_mesh_t *m, const ck_topo_t *topo, int64_t **comp,
                             int64_t *ncomp)
{
  int64_t *par = NULL;
  I2M_CALL(i2m_malloc((size_t)m->nt, sizeof *par, &par));
  for (int64_t t = 0; t < m->nt; t++) par[t] = t;
  for (int64_t id = 0; id < 4 * m->nt; id++) {
    int64_t nb = topo->nb[id];
    if (nb >= 0 && m->tet_label[nb / 4] == m->tet_label[id / 4]) ck_uf_union(par, id / 4, nb / 4);
  }
  *ncomp = 0;
  for (int64_t t = 0; t < m->nt; t++) {
    int64_t r = ck_uf_find(par, t);
    if (r == t) (*ncomp)++;
    par[t] = r;
  }
  *comp = par;
  return I2M_OK;
}

/* ---- per-label figures ---- */
static int cmp_i64(const void *a, const void *b)
{
  int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x > y) - (x < y);
}

static int64_t label_slot(const ck_fidelity_t *f, int64_t value)
{
  int lo = 0, hi = f->nlabels - 1;
  while (lo < hi) {
    int mid = (lo + hi) / 2;
    if (f->labels[mid].value < value)
      lo = mid + 1;
    else
      hi = mid;
  }
  return f->nlabels && f->labels[lo].value == value ? lo : -1;
}

/* The volume of a piece's tets per image component that holds their circumcentres: open
 * addressing on the component, the slots in use listed for the next piece. */
typedef struct {
  int64_t *key; /* the component, -1: empty */
  double *w;
  int64_t *used, n, cap;
} votes_t;

static i2m_err_t votes_grow(votes_t *V)
{
  const int64_t cap = V->cap ? 2 * V->cap : 64, n = V->n;
  int64_t *key = V->key, *used = V->used;
  double *w = V->w;
  V->key = NULL, V->w = NULL, V->used = NULL;
  i2m_err_t err = i2m_malloc((size_t)cap, sizeof *V->key, &V->key);
  if (err == I2M_OK) err = i2m_malloc((size_t)cap, sizeof *V->w, &V->w);
  if (err == I2M_OK) err = i2m_malloc((size_t)cap, sizeof *V->used, &V->used);
  if (err == I2M_OK) {
    for (int64_t i = 0; i < cap; i++) V->key[i] = -1;
    V->cap = cap;
    V->n = 0;
    for (int64_t i = 0; i < n; i++) { /* (in the order they came: the sums' order is kept) */
      int64_t h = (int64_t)((uint64_t)key[used[i]] * 0x9E3779B97F4A7C15ull >> 20) & (cap - 1);
      while (V->key[h] >= 0) h = (h + 1) & (cap - 1);
      V->key[h] = key[used[i]];
      V->w[h] = w[used[i]];
      V->used[V->n++] = h;
    }
  }
  i2m_free(&key);
  i2m_free(&w);
  i2m_free(&used);
  return err;
}

static i2m_err_t votes_add(votes_t *V, int64_t comp, double w)
{
  if (2 * (V->n + 1) > V->cap) I2M_CALL(votes_grow(V));
  int64_t h = (int64_t)((uint64_t)comp * 0x9E3779B97F4A7C15ull >> 20) & (V->cap - 1);
  while (V->key[h] >= 0 && V->key[h] != comp) h = (h + 1) & (V->cap - 1);
  if (V->key[h] < 0) {
    V->key[h] = comp;
    V->w[h] = 0.0;
    V->used[V->n++] = h;
  }
  V->w[h] += w;
  return I2M_OK;
}

/* The component with the most volume (the smallest of those tied), and the table emptied. */
static int64_t votes_best(votes_t *V)
{
  int64_t best = -1;
  double bw = -1;
  for (int64_t i = 0; i < V->n; i++) {
    const int64_t h = V->used[i];
    if (V->w[h] > bw || (V->w[h] == bw && V->key[h] < best)) {
      bw = V->w[h];
      best = V->key[h];
    }
    V->key[h] = -1;
  }
  V->n = 0;
  return best;
}

static void votes_free(votes_t *V)
{
  i2m_free(&V->key);
  i2m_free(&V->w);
  i2m_free(&V->used);
}

/* The image component a tet's circumcentre lies in, if it is a voxel of the tet's label (-1). */
static int64_t centre_component(const ck_mesh_t *m, const double *g, const i2m_image_t *img,
                                const i2m_components_t *runs, int64_t t)
{
  const int64_t *q = m->tet + 4 * t;
  double c[3];
  if (!ck_circumcentre(g + 3 * q[0], g + 3 * q[1], g + 3 * q[2], g + 3 * q[3], c)) return -1;
  int64_t v[3];
  if (!i2m_image_voxel_at(img, c, v)) return -1;
  const int l = i2m_image_label_voxel(img, v[0], v[1], v[2]);
  if (img->label_value[l] != m->tet_label[t]) return -1;
  return i2m_components_find(runs, v[0], v[1], v[2]);
}

/* For every image component, the mesh pieces that stand for it (comp: each tet's piece). */
static i2m_err_t component_pieces(const ck_mesh_t *m, const ck_topo_t *topo, const double *g, const i2m_image_t *img,
                                  const i2m_components_t *runs, const int64_t *comp, ck_fidelity_t *f, ck_progress_t *pr)
{
  int64_t *pieces = NULL, *cc = NULL, *pos = NULL, *order = NULL;
  votes_t V = {NULL, NULL, NULL, 0, 0};
  i2m_err_t err = I2M_OK;
  const int64_t nt = m->nt;
  I2M_CALL(i2m_malloc((size_t)(nt ? nt : 1), sizeof *cc, &cc));
  I2M_CALL_GOTO(err, out, i2m_calloc((size_t)nt + 1, sizeof *pos, &pos));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)(nt ? nt : 1), sizeof *order, &order));
  CK_OMP("omp parallel for schedule(dynamic, 8192)")
  for (int64_t t = 0; t < nt; t++) {
    cc[t] = centre_component(m, g, img, runs, t);
    if (t % 65536 == 65535) ck_progress_add(pr, 65536);
  }
  /* the voting tets bucketed by piece, in the tets' order (a counting sort: pos[p] is where
   * piece p's next vote goes, and after the fill where its votes end) */
  for (int64_t t = 0; t < nt; t++) pos[comp[t] + 1] += cc[t] >= 0;
  for (int64_t t = 0; t < nt; t++) pos[t + 1] += pos[t];
  for (int64_t t = 0; t < nt; t++)
    if (cc[t] >= 0) order[pos[comp[t]]++] = t;
  I2M_CALL_GOTO(err, out, i2m_calloc((size_t)(runs->nruns ? runs->nruns : 1), sizeof *pieces, &pieces));
  for (int64_t p = 0; p < nt; p++) { /* each piece: the component with the most volume */
    const int64_t begin = p ? pos[p - 1] : 0, end = pos[p];
    if (begin == end) continue;
    for (int64_t k = begin; k < end; k++) I2M_CALL_GOTO(err, out, votes_add(&V, cc[order[k]], fabs(topo->vol[order[k]])));
    pieces[votes_best(&V)]++;
  }
  for (int64_t r = 0; r < runs->nruns; r++) {
    if (runs->par[r] != r || runs->lab[r] == 0) continue;
    if (f->ncomponents % 256 == 0)
      I2M_CALL_GOTO(err, out, i2m_realloc((size_t)f->ncomponents + 256, sizeof *f->components, &f->components));
    f->components[f->ncomponents++] = (ck_component_t){img->label_value[runs->lab[r]], runs->size[r], pieces[r]};
  }
out:
  i2m_free(&cc);
  i2m_free(&pos);
  i2m_free(&order);
  i2m_free(&pieces);
  votes_free(&V);
  return err;
}

static i2m_err_t label_table(const ck_mesh_t *m, const ck_topo_t *topo, const double *g, const i2m_image_t *img,
                             i2m_components_t *runs, ck_fidelity_t *f)
{
  int64_t *vals = NULL, nv = 0, *comp = NULL, ncomp;
  I2M_CALL(i2m_malloc((size_t)(m->nt + img->nlabels), sizeof *vals, &vals));
  for (int l = 1; l < img->nlabels; l++)
    if (img->label_count[l] > 0) vals[nv++] = img->label_value[l];
  for (int64_t t = 0; t < m->nt; t++) /* (a run of one label, common in the tets' order, once) */
    if (t == 0 || m->tet_label[t] != m->tet_label[t - 1]) vals[nv++] = m->tet_label[t];
  qsort(vals, (size_t)nv, sizeof *vals, cmp_i64);
  int64_t nd = 0; /* image values are never 0 (l >= 1); tets of label 0 get a slot too */
  for (int64_t i = 0; i < nv; i++)
    if (nd == 0 || vals[i] != vals[nd - 1]) vals[nd++] = vals[i];
  i2m_err_t err = i2m_calloc((size_t)nd, sizeof *f->labels, &f->labels);
  if (err != I2M_OK) goto out;
  f->nlabels = (int)nd;
  double vvol = img->spacing[0] * img->spacing[1] * img->spacing[2];
  for (int64_t i = 0; i < nd; i++) f->labels[i].value = vals[i];
  for (int l = 1; l < img->nlabels; l++) {
    int64_t s = label_slot(f, img->label_value[l]);
    if (s < 0) continue;
    f->labels[s].voxels = img->label_count[l];
    f->labels[s].image_volume = (double)img->label_count[l] * vvol;
    f->labels[s].in_image = img->label_count[l] > 0;
  }
  for (int64_t r = 0; r < runs->nruns; r++) {
    if (runs->par[r] != r || runs->lab[r] == 0) continue;
    int64_t s = label_slot(f, img->label_value[runs->lab[r]]);
    ck_label_t *L = &f->labels[s];
    L->image_components++;
    L->image_components_100 += runs->size[r] >= 100;
    if (runs->size[r] > L->largest_component) L->largest_component = runs->size[r];
    f->image_components_total++;
  }
  ck_progress_t pr; /* three passes over the tets: volumes, pieces, circumcentres */
  ck_progress_begin(&pr, "fidelity, label volumes and components (3 passes)", "tets", 3 * m->nt);
  for (int64_t t = 0; t < m->nt; t++) {
    if (t % 65536 == 0 && t > 0) ck_progress_to(&pr, t);
    ck_label_t *L = &f->labels[label_slot(f, m->tet_label[t])];
    L->mesh_volume += topo->vol[t];
    L->tets++;
    L->in_mesh = 1;
  }
  I2M_CALL_GOTO(err, out, ck_mesh_components(m, topo, &comp, &ncomp));
  ck_progress_to(&pr, 2 * m->nt);
  for (int64_t t = 0; t < m->nt; t++)
    if (comp[t] == t) f->labels[label_slot(f, m->tet_label[t])].mesh_components++;
  I2M_CALL_GOTO(err, out, component_pieces(m, topo, g, img, runs, comp, f, &pr));
  ck_progress_set(&pr, 3 * m->nt);
  ck_progress_end(&pr);
  for (int i = 0; i < f->nlabels; i++) {
    ck_label_t *L = &f->labels[i];
    L->rel_error_pct = L->image_volume > 0 ? 100.0 * (L->mesh_volume - L->image_volume) / L->image_volume
                                           : (L->mesh_volume > 0 ? INFINITY : 0.0);
    f->missing_labels += L->in_image && !L->in_mesh;
    f->extra_labels += L->in_mesh && !L->in_image;
  }
out:
  i2m_free(&vals);
  i2m_free(&comp);
  return err;
}

/* ---- driver ---- */

static i2m_err_t grid_build_counted(ck_grid_t *g, int64_t n, ck_bbox_fn bbox, const void *ctx, const char *phase,
                                    const char *unit)
{
  ck_progress_t pr;
  ck_progress_begin(&pr, phase, unit, 2 * n);
  const i2m_err_t err = ck_grid_build(g, n, bbox, ctx, &pr);
  ck_progress_set(&pr, 2 * n);
  ck_progress_end(&pr);
  return err;
}

static i2m_err_t build_face_grid(const i2m_image_t *img, const fctx_t *fc, int64_t nf, ck_grid_t *g)
{
  /* cells of about two of the smallest voxel sizes, at least one voxel, at most 2^23 cells */
  double smin = fmin(img->spacing[0], fmin(img->spacing[1], img->spacing[2]));
  for (double scale = 2.0;; scale *= 1.25) {
    double ncell = 1;
    for (int a = 0; a < 3; a++) {
      int64_t cv = (int64_t)floor(scale * smin / img->spacing[a] + 0.5);
      if (cv < 1) cv = 1;
      g->h[a] = (double)cv * img->spacing[a];
      g->lo[a] = -0.5 * img->spacing[a] - 1e-9 * g->h[a];
      g->n[a] = (img->n[a] + 1 + cv - 1) / cv + 1;
      ncell *= (double)g->n[a];
    }
    if (ncell <= (double)((int64_t)1 << 23)) break;
  }
  return grid_build_counted(g, nf, face_bbox, fc, "fidelity, search grid of the image faces (2 passes)", "faces");
}

static i2m_err_t build_tri_grid(const tctx_t *tc, int64_t ntri, double min_h, ck_grid_t *g)
{
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  double elen = 0;
  for (int64_t t = 0; t < ntri; t++) {
    double a[3], b[3];
    tri_bbox(tc, t, a, b);
    for (int k = 0; k < 3; k++) {
      lo[k] = fmin(lo[k], a[k]);
      hi[k] = fmax(hi[k], b[k]);
      elen += b[k] - a[k];
    }
  }
  if (ntri == 0) {
    for (int k = 0; k < 3; k++) lo[k] = hi[k] = 0;
  }
  double h = ntri ? fmax(elen / (3.0 * (double)ntri), min_h) : 1.0;
  double vol = (hi[0] - lo[0] + h) * (hi[1] - lo[1] + h) * (hi[2] - lo[2] + h);
  while (vol / (h * h * h) > 4.0 * (double)ntri + 1000.0) h *= 1.26;
  for (int k = 0; k < 3; k++) {
    g->h[k] = h;
    g->lo[k] = lo[k] - 1e-9 * h;
    g->n[k] = (int64_t)((hi[k] - lo[k]) / h) + 1;
  }
  return grid_build_counted(g, ntri, tri_bbox, tc, "fidelity, search grid of the mesh interfaces (2 passes)",
                            "triangles");
}

/* The shortest run, in mm, of voxel c's label through c along one of the image axes (0 for a
 * voxel outside the image). */
static double thinnest_run(const i2m_image_t *img, const int64_t c[3])
{
  if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] >= img->n[0] || c[1] >= img->n[1] || c[2] >= img->n[2]) return 0;
  const int l = i2m_image_label_voxel(img, c[0], c[1], c[2]);
  double best = INFINITY;
  for (int a = 0; a < 3; a++) {
    int64_t n = 1, q[3] = {c[0], c[1], c[2]};
    for (q[a] = c[a] - 1; q[a] >= 0 && i2m_image_label_voxel(img, q[0], q[1], q[2]) == l; q[a]--) n++;
    for (q[a] = c[a] + 1; q[a] < img->n[a] && i2m_image_label_voxel(img, q[0], q[1], q[2]) == l; q[a]++) n++;
    const double len = (double)n * img->spacing[a];
    best = len < best ? len : best;
  }
  return best;
}

static void worst_face(const i2m_image_t *img, i2m_components_t *runs, const vface_t *fc, ck_fidelity_t *f)
{
  int64_t c0[3] = {fc->c[0], fc->c[1], fc->c[2]}, c1[3] = {fc->c[0], fc->c[1], fc->c[2]};
  c1[fc->axis]++;
  int l0 = i2m_image_label_voxel(img, c0[0], c0[1], c0[2]);
  int l1 = i2m_image_label_voxel(img, c1[0], c1[1], c1[2]);
  int64_t v0 = img->label_value[l0], v1 = img->label_value[l1];
  int64_t s0 = voxel_component(runs, c0[0], c0[1], c0[2]);
  int64_t s1 = voxel_component(runs, c1[0], c1[1], c1[2]);
  int sw = v0 > v1;
  f->worst_pair[0] = sw ? v1 : v0;
  f->worst_pair[1] = sw ? v0 : v1;
  f->worst_component[0] = sw ? s1 : s0;
  f->worst_component[1] = sw ? s0 : s1;
  const double w0 = thinnest_run(img, c0), w1 = thinnest_run(img, c1);
  f->worst_thinnest[0] = sw ? w1 : w0;
  f->worst_thinnest[1] = sw ? w0 : w1;
}

i2m_err_t ck_fidelity(const ck_mesh_t *m, const ck_topo_t *topo, const i2m_image_t *img, int distances,
                      ck_fidelity_t *f)
{
  double *g = NULL;
  vface_t *faces = NULL;
  int64_t nf = 0, worst = -1;
  ck_grid_t fg = {0}, tg = {0};
  i2m_components_t runs = {0};
  pooled_t pool = {{NULL, NULL}, {NULL, NULL}, {0, 0}};
  fctx_t fc = {img, NULL, NULL};
  i2m_err_t err = I2M_OK;
  memset(f, 0, sizeof *f);
  f->min_spacing = fmin(img->spacing[0], fmin(img->spacing[1], img->spacing[2]));
  f->sample_spacing = f->min_spacing / 2;
  I2M_CALL(i2m_malloc((size_t)m->nv * 3, sizeof *g, &g));
  double ext = 1e6 * (double)(img->n[0] + img->n[1] + img->n[2]) *
               fmax(img->spacing[0], fmax(img->spacing[1], img->spacing[2]));
  for (int64_t v = 0; v < m->nv; v++) {
    i2m_image_world_to_grid(img, m->xyz + 3 * v, g + 3 * v);
    for (int a = 0; a < 3; a++)
      I2M_CHECK_GOTO(fabs(g[3 * v + a]) < ext, err, out, I2M_ERR_INPUT,
                     "%s: vertex %lld at (%g, %g, %g) is absurdly far from the image %s: no "
                     "fidelity figures", m->path, (long long)v, m->xyz[3 * v], m->xyz[3 * v + 1],
                     m->xyz[3 * v + 2], img->path);
  }
  f->distances = distances;
  if (!distances) {
    I2M_CALL_GOTO(err, out, i2m_image_components(img, &runs));
    I2M_CALL_GOTO(err, out, label_table(m, topo, g, img, &runs, f));
    goto out;
  }
  I2M_CALL_GOTO(err, out, image_faces(img, &faces, &nf));
  fc.f = faces;
  tctx_t tc = {g, topo->iface.v};
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nf * 6, sizeof *fc.box, &fc.box));
  for (int64_t i = 0; i < nf; i++) face_box(&fc, i, fc.box + 6 * i, fc.box + 6 * i + 3);
  I2M_CALL_GOTO(err, out, build_face_grid(img, &fc, nf, &fg));
  I2M_CALL_GOTO(err, out, build_tri_grid(&tc, topo->iface.n, f->min_spacing, &tg));
  double t0 = i2m_wtime();
  I2M_CALL_GOTO(err, out, mesh_to_image(&tc, topo->iface.n, &fg, &fc, f->sample_spacing, img, f, &pool));
  double t1 = i2m_wtime();
  I2M_CALL_GOTO(err, out, image_to_mesh(faces, nf, &tg, &tc, img, f, &worst, &pool));
  double t2 = i2m_wtime();
  I2M_CALL_GOTO(err, out, i2m_image_components(img, &runs));
  double t3 = i2m_wtime();
  f->t_mesh_to_image = t1 - t0;
  f->t_image_to_mesh = t2 - t1;
  f->t_components = t3 - t2;
  if (worst >= 0) worst_face(img, &runs, faces + worst, f);
  I2M_CALL_GOTO(err, out, label_table(m, topo, g, img, &runs, f));
  ck_dist_t *a = &f->mesh_to_image, *b = &f->image_to_mesh, *t = &f->two_sided;
  *t = a->max >= b->max ? *a : *b;
  /* two-sided distribution: both directed distance sets pooled, each sample weighted by the
   * surface area it stands for (mesh triangles and image faces alike) */
  t->p99 = weighted_quantile(&pool, 0, 1, 0.99);
  t->count = a->count + b->count;
  t->mean = t->count ? (a->mean * (double)a->count + b->mean * (double)b->count) / (double)t->count : 0;
out:
  i2m_free(&g);
  i2m_free(&faces);
  i2m_free(&fc.box);
  ck_grid_free(&fg);
  ck_grid_free(&tg);
  i2m_components_free(&runs);
  pooled_free(&pool);
  return err;
}

void ck_fidelity_free(ck_fidelity_t *f)
{
  i2m_free(&f->labels);
  i2m_free(&f->components);
}

void ck_fidelity_whole(ck_fidelity_t *f, int64_t min_voxels)
{
  for (int i = 0; i < f->nlabels; i++) f->labels[i].large_components = f->labels[i].split_components = 0;
  for (int64_t k = 0; k < f->ncomponents; k++) {
    const ck_component_t *c = &f->components[k];
    if (c->voxels < min_voxels) continue;
    ck_label_t *L = &f->labels[label_slot(f, c->value)];
    L->large_components++;
    L->split_components += c->pieces != 1;
  }
}
