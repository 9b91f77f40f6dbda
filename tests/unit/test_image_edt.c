/* Unit tests of the image oracles (layer 2): the feature transform is exact (every voxel's
 * feature is a nearest boundary voxel, by brute force); the closest interface point lies on
 * an interface and is within half a voxel diagonal of the true distance; the early-out
 * bound never hides a point within reach; bisection brackets a label change; connected
 * components agree with a flood fill. */
#include <math.h>
#include <stdlib.h>

#include "i2m/edt.h"
#include "test_util.h"

static uint64_t rng = 0x1234567ull;
static double urand(void)
{
  rng ^= rng << 13;
  rng ^= rng >> 7;
  rng ^= rng << 17;
  return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

/* Random blobs of labels 0..3 in an n0 x n1 x n2 image with anisotropic spacing. */
static i2m_image_t *random_image(int64_t n0, int64_t n1, int64_t n2, double fill)
{
  int64_t n[3] = {n0, n1, n2};
  double sp[3] = {0.7, 1.0, 1.9};
  int64_t *v = calloc((size_t)(n0 * n1 * n2), sizeof *v);
  for (int b = 0; b < 6; b++) { /* a few random balls */
    double c[3] = {urand() * n0, urand() * n1, urand() * n2}, r = 1 + fill * urand() * n0;
    int64_t lab = 1 + b % 3;
    for (int64_t k = 0; k < n2; k++)
      for (int64_t j = 0; j < n1; j++)
        for (int64_t i = 0; i < n0; i++) {
          double d = sqrt(pow((i - c[0]) * sp[0], 2) + pow((j - c[1]) * sp[1], 2) + pow((k - c[2]) * sp[2], 2));
          if (d < r) v[(k * n1 + j) * n0 + i] = lab;
        }
  }
  i2m_image_t *img = NULL;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, NULL, NULL, v, &img) == I2M_OK);
  free(v);
  return img;
}

static bool is_boundary(const i2m_image_t *img, int64_t i, int64_t j, int64_t k)
{
  int l = i2m_image_label_voxel(img, i, j, k);
  const int64_t d[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int q = 0; q < 6; q++)
    if (i2m_image_label_voxel(img, i + d[q][0], j + d[q][1], k + d[q][2]) != l) return true;
  return false;
}

/* Brute force: exact distance from p to the nearest interface face (squares between voxels
 * of different labels, outside counting as 0). */
static double brute_face_distance(const i2m_image_t *img, const double p[3])
{
  double best = INFINITY;
  for (int64_t k = -1; k < img->n[2]; k++)
    for (int64_t j = -1; j < img->n[1]; j++)
      for (int64_t i = -1; i < img->n[0]; i++)
        for (int ax = 0; ax < 3; ax++) {
          int64_t c[3] = {i, j, k}, n[3] = {i, j, k};
          n[ax]++;
          if (i2m_image_label_voxel(img, c[0], c[1], c[2]) == i2m_image_label_voxel(img, n[0], n[1], n[2])) continue;
          double d2 = 0;
          for (int a = 0; a < 3; a++) {
            double s = img->spacing[a], q;
            if (a == ax) q = (c[a] + 0.5) * s;
            else q = fmin(fmax(p[a], (c[a] - 0.5) * s), (c[a] + 0.5) * s);
            d2 += (p[a] - q) * (p[a] - q);
          }
          best = fmin(best, d2);
        }
  return sqrt(best);
}

static void test_feature_transform_exact(void)
{
  for (int trial = 0; trial < 4; trial++) {
    i2m_image_t *img = random_image(13, 11, 9, 0.4);
    i2m_edt_t *e = NULL;
    CU_ASSERT_FATAL(i2m_edt_create(img, &e) == I2M_OK);
    CU_ASSERT(e->nboundary > 0);
    for (int64_t k = 0; k < e->m[2]; k++)
      for (int64_t j = 0; j < e->m[1]; j++)
        for (int64_t i = 0; i < e->m[0]; i++) {
          int64_t f = i2m_edt_feature(e, (k * e->m[1] + j) * e->m[0] + i);
          CU_ASSERT_FATAL(f < e->m[0] * e->m[1] * e->m[2]);
          CU_ASSERT(i2m_edt_label_voxel(e, e->lo[0] + i, e->lo[1] + j, e->lo[2] + k) ==
                    i2m_image_label_voxel(img, e->lo[0] + i, e->lo[1] + j, e->lo[2] + k));
          int64_t fi = f % e->m[0], fj = (f / e->m[0]) % e->m[1], fk = f / (e->m[0] * e->m[1]);
          int64_t v[3] = {e->lo[0] + i, e->lo[1] + j, e->lo[2] + k}, b[3] = {e->lo[0] + fi, e->lo[1] + fj, e->lo[2] + fk};
          CU_ASSERT(is_boundary(img, b[0], b[1], b[2]));
          double dft = 0, best = INFINITY;
          for (int a = 0; a < 3; a++) dft += pow((double)(v[a] - b[a]) * img->spacing[a], 2);
          for (int64_t kk = 0; kk < img->n[2]; kk++) /* nearest boundary voxel centre, brute force */
            for (int64_t jj = 0; jj < img->n[1]; jj++)
              for (int64_t ii = 0; ii < img->n[0]; ii++)
                if (is_boundary(img, ii, jj, kk)) {
                  double d = pow((double)(v[0] - ii) * img->spacing[0], 2) + pow((double)(v[1] - jj) * img->spacing[1], 2) +
                             pow((double)(v[2] - kk) * img->spacing[2], 2);
                  best = fmin(best, d);
                }
          CU_ASSERT_DOUBLE_EQUAL(dft, best, 1e-9);
        }
    i2m_edt_destroy(&e);
    i2m_image_destroy(&img);
  }
}

static void test_closest_point(void)
{
  i2m_image_t *img = random_image(14, 12, 8, 0.4);
  i2m_edt_t *e = NULL;
  CU_ASSERT_FATAL(i2m_edt_create(img, &e) == I2M_OK);
  double hdiag = 0.5 * sqrt(pow(img->spacing[0], 2) + pow(img->spacing[1], 2) + pow(img->spacing[2], 2));
  for (int q = 0; q < 400; q++) { /* points inside and well outside the image */
    e->labels_packed = q % 2 == 0; /* labels from the packed words, and from the image */
    double p[3], z[3];
    for (int a = 0; a < 3; a++) p[a] = (urand() * 1.6 - 0.3) * (double)img->n[a] * img->spacing[a];
    int pair[2];
    double d = sqrt(i2m_edt_closest(e, p, INFINITY, z, pair));
    double truth = brute_face_distance(img, p);
    CU_ASSERT(d >= truth - 1e-9);          /* z is an interface point ... */
    CU_ASSERT(d <= truth + 2 * hdiag);    /* ... close to the nearest one */
    CU_ASSERT(pair[0] < pair[1]);
    /* the refinement's probe (world frame: the same here; label and closest point at once,
     * from the voxel index it is handed) agrees, inside and outside the box K */
    i2m_edt_probe_t pr;
    i2m_edt_probe_world(e, p, INFINITY, &pr);
    CU_ASSERT(pr.label == i2m_image_label_at(img, p));
    CU_ASSERT_DOUBLE_EQUAL(sqrt(pr.d2), d, 1e-9);
    CU_ASSERT(pr.pair[0] == pair[0] && pr.pair[1] == pair[1]);
    /* z is on an interface of the pair it reports: both labels occur right around z (z may
     * lie on a face's edge or corner, so look at all eight nudged copies) */
    bool seen[2] = {false, false};
    for (int c = 0; c < 8; c++) {
      double zz[3];
      for (int a = 0; a < 3; a++) zz[a] = z[a] + ((c >> a) & 1 ? 1e-6 : -1e-6);
      int l = i2m_image_label_at(img, zz);
      seen[0] = seen[0] || l == pair[0];
      seen[1] = seen[1] || l == pair[1];
    }
    CU_ASSERT(seen[0] && seen[1]);
    /* the early-out bound never answers "farther" for a point within reach */
    double r2 = pow(truth + 0.01, 2);
    CU_ASSERT(isfinite(i2m_edt_closest(e, p, r2, z, NULL)) || d * d > r2);
  }
  i2m_edt_destroy(&e);
  i2m_image_destroy(&img);
}

static void test_no_interface(void)
{
  int64_t n[3] = {5, 4, 3}, v[60] = {0};
  double sp[3] = {1, 1, 1}, p[3] = {1, 1, 1}, z[3];
  i2m_image_t *img = NULL;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, NULL, NULL, v, &img) == I2M_OK);
  i2m_edt_t *e = NULL;
  CU_ASSERT_FATAL(i2m_edt_create(img, &e) == I2M_OK);
  CU_ASSERT_EQUAL(e->nboundary, 0);
  CU_ASSERT(isinf(i2m_edt_closest(e, p, INFINITY, z, NULL)));
  i2m_edt_destroy(&e);
  i2m_image_destroy(&img);
}

static void test_bisection(void)
{
  i2m_image_t *img = random_image(12, 12, 10, 0.5);
  i2m_edt_t *e = NULL;
  CU_ASSERT_FATAL(i2m_edt_create(img, &e) == I2M_OK);
  CU_ASSERT(e->labels_packed);
  int found = 0;
  for (int q = 0; q < 300; q++) {
    e->labels_packed = q % 2 == 0; /* the packed labels, and the image's (same answers) */
    double a[3], b[3], x[3];
    for (int k = 0; k < 3; k++) {
      a[k] = urand() * (double)img->n[k] * img->spacing[k];
      b[k] = urand() * (double)img->n[k] * img->spacing[k];
    }
    if (i2m_image_label_at(img, a) == i2m_image_label_at(img, b)) continue;
    int la, lb;
    double tol = 1e-4;
    i2m_edt_bisect(e, a, b, tol, x, &la, &lb);
    found++;
    CU_ASSERT_EQUAL(la, i2m_image_label_at(img, a));
    CU_ASSERT(la != lb);
    /* x is within tol of a point where the label leaves la: step back and forth along ab */
    double L = sqrt(pow(b[0] - a[0], 2) + pow(b[1] - a[1], 2) + pow(b[2] - a[2], 2));
    double p0[3], p1[3];
    for (int k = 0; k < 3; k++) {
      p0[k] = x[k] - (b[k] - a[k]) / L * tol;
      p1[k] = x[k] + (b[k] - a[k]) / L * tol;
    }
    CU_ASSERT(i2m_image_label_at(img, p0) != i2m_image_label_at(img, p1) || i2m_image_label_at(img, p0) == la);
  }
  CU_ASSERT(found > 50);
  i2m_edt_destroy(&e);
  i2m_image_destroy(&img);
}

/* 6-connected components of random blobs against a flood fill: two voxels share a root
 * exactly when the fill reaches one from the other, and the size is the fill's count; a
 * block's components see only the block. */
static void image_row(const void *ctx, int64_t i0, int64_t j, int64_t k, int64_t n, uint16_t *out)
{
  for (int64_t i = 0; i < n; i++) out[i] = (uint16_t)i2m_image_label_voxel((const i2m_image_t *)ctx, i0 + i, j, k);
}

static void test_components(void)
{
  i2m_image_t *img = random_image(14, 11, 9, 0.25);
  const int64_t *n = img->n, nv = n[0] * n[1] * n[2];
  i2m_components_t c;
  CU_ASSERT_FATAL(i2m_image_components(img, &c) == I2M_OK);
  int64_t *fill = malloc((size_t)nv * sizeof *fill), *stack = malloc((size_t)nv * sizeof *stack);
  for (int64_t v = 0; v < nv; v++) fill[v] = -1;
  int ncomp = 0;
  for (int64_t s = 0; s < nv; s++) {
    if (fill[s] >= 0) continue;
    int64_t top = 0, count = 0;
    const int lab = i2m_image_index(img, s);
    fill[s] = s;
    stack[top++] = s;
    while (top > 0) {
      const int64_t v = stack[--top], i = v % n[0], j = v / n[0] % n[1], k = v / (n[0] * n[1]);
      const int64_t nb[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k}, {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
      count++;
      for (int q = 0; q < 6; q++) {
        const int64_t *x = nb[q];
        if (x[0] < 0 || x[1] < 0 || x[2] < 0 || x[0] >= n[0] || x[1] >= n[1] || x[2] >= n[2]) continue;
        const int64_t w = (x[2] * n[1] + x[1]) * n[0] + x[0];
        if (fill[w] < 0 && i2m_image_index(img, w) == lab) {
          fill[w] = s;
          stack[top++] = w;
        }
      }
    }
    ncomp++;
    const int64_t root = i2m_components_find(&c, s % n[0], s / n[0] % n[1], s / (n[0] * n[1]));
    CU_ASSERT_EQUAL(c.size[root], count);
  }
  CU_ASSERT(ncomp > 3);
  int64_t *root_of_fill = malloc((size_t)nv * sizeof *root_of_fill);
  for (int64_t v = 0; v < nv; v++) root_of_fill[v] = -1;
  for (int64_t v = 0; v < nv; v++) { /* the fills and the roots correspond one to one */
    const int64_t root = i2m_components_find(&c, v % n[0], v / n[0] % n[1], v / (n[0] * n[1]));
    if (root_of_fill[fill[v]] < 0) root_of_fill[fill[v]] = root;
    CU_ASSERT_EQUAL(root_of_fill[fill[v]], root);
    CU_ASSERT_EQUAL(c.lab[root], i2m_image_index(img, v));
    const int lab = i2m_image_index(img, v); /* the label from the runs: the voxel's own only */
    CU_ASSERT_EQUAL(i2m_components_find_label(&c, v % n[0], v / n[0] % n[1], v / (n[0] * n[1]), lab), root);
    CU_ASSERT_EQUAL(i2m_components_find_label(&c, v % n[0], v / n[0] % n[1], v / (n[0] * n[1]), lab + 1), -1);
  }
  int64_t nroots = 0;
  for (int64_t r = 0; r < c.nruns; r++) nroots += c.par[r] == r;
  CU_ASSERT_EQUAL(nroots, ncomp);
  i2m_components_free(&c);
  const int64_t lo[3] = {2, 1, 3}, bn[3] = {5, 6, 4}; /* a block: only its voxels */
  CU_ASSERT_FATAL(i2m_components_build(lo, bn, image_row, img, &c) == I2M_OK);
  CU_ASSERT_EQUAL(i2m_components_find(&c, 1, 1, 3), -1);
  CU_ASSERT_EQUAL(i2m_components_find(&c, 7, 1, 3), -1);
  CU_ASSERT_EQUAL(i2m_components_find_label(&c, 7, 1, 3, i2m_image_label_voxel(img, 7, 1, 3)), -1); /* (outside) */
  int64_t total = 0;
  for (int64_t r = 0; r < c.nruns; r++) total += c.par[r] == r ? c.size[r] : 0;
  CU_ASSERT_EQUAL(total, bn[0] * bn[1] * bn[2]);
  CU_ASSERT(i2m_components_find(&c, 2, 1, 3) >= 0);
  i2m_components_free(&c);
  free(fill);
  free(stack);
  free(root_of_fill);
  i2m_image_destroy(&img);
}

/* ---- the transform in shares (i2m_edt_create_shared), processes simulated by threads ---- */

#ifdef _OPENMP
#include <omp.h>
#include <string.h>

typedef struct {
  int32_t *buf[8]; /* each part's array, shared at each exchange */
  int failed;      /* some part passed an error */
  int fail_part;   /* the part that fails at its first exchange (-1: none) */
  int calls[8];
} sim_t;

/* The exchange between the team's threads: each copies the others' ranges from their arrays. */
static i2m_err_t sim_exchange(void *ctx, i2m_err_t err, int32_t *buf, const int64_t *count, const int64_t *displ,
                              int64_t nblocks, int64_t stride)
{
  sim_t *S = ctx;
  const int me = omp_get_thread_num(), P = omp_get_num_threads();
  if (me == S->fail_part && S->calls[me] == 0) err = I2M_ERR_MEMORY;
  S->calls[me]++;
  if (err != I2M_OK) {
#pragma omp atomic write
    S->failed = 1;
  }
  S->buf[me] = buf;
#pragma omp barrier
  int failed;
#pragma omp atomic read
  failed = S->failed;
  for (int q = 0; q < P && !failed; q++)
    for (int64_t b = 0; q != me && b < nblocks; b++)
      memcpy(buf + b * stride + displ[q], S->buf[q] + b * stride + displ[q], (size_t)count[q] * sizeof *buf);
#pragma omp barrier
  return failed ? I2M_ERR_MEMORY : I2M_OK;
}

/* P parts (threads) compute the transform of img together; each part's result into e[part]. */
static void shared_edt(const i2m_image_t *img, int P, int fail_part, i2m_edt_t **e, i2m_err_t *err)
{
  sim_t S;
  memset(&S, 0, sizeof S);
  S.fail_part = fail_part;
#pragma omp parallel num_threads(P)
  {
    const int q = omp_get_thread_num();
    const i2m_edt_share_t share = {q, P, sim_exchange, &S};
    err[q] = i2m_edt_create_shared(img, &share, &e[q]);
  }
}
#endif

/* Computed in 2, 3 or 5 shares (more than some axes have slices: empty shares), the transform
 * is the one computed alone, word for word; an error in one share is every share's (none
 * hangs). */
static void test_shared(void)
{
#ifdef _OPENMP
  const int64_t dims[2][3] = {{37, 23, 17}, {19, 4, 3}};
  for (int d = 0; d < 2; d++) {
    i2m_image_t *img = random_image(dims[d][0], dims[d][1], dims[d][2], 0.3);
    i2m_edt_t *alone = NULL;
    CU_ASSERT_FATAL(i2m_edt_create(img, &alone) == I2M_OK);
    const int64_t nbox = alone->m[0] * alone->m[1] * alone->m[2];
    CU_ASSERT_FATAL(nbox > 0 && alone->nboundary > 0);
    for (int P = 2; P <= 5; P += P == 3 ? 2 : 1) {
      i2m_edt_t *e[8] = {NULL};
      i2m_err_t err[8];
      shared_edt(img, P, -1, e, err);
      for (int q = 0; q < P; q++) {
        CU_ASSERT_EQUAL_FATAL(err[q], I2M_OK);
        CU_ASSERT_EQUAL(e[q]->nboundary, alone->nboundary);
        CU_ASSERT_EQUAL(e[q]->labels_packed, alone->labels_packed);
        CU_ASSERT_EQUAL(e[q]->feat_mask, alone->feat_mask);
        CU_ASSERT(memcmp(e[q]->ft, alone->ft, (size_t)nbox * sizeof *alone->ft) == 0);
        i2m_edt_destroy(&e[q]);
      }
      shared_edt(img, P, P - 1, e, err); /* the last part fails at its first exchange */
      for (int q = 0; q < P; q++) {
        CU_ASSERT_NOT_EQUAL(err[q], I2M_OK);
        CU_ASSERT_PTR_NULL(e[q]);
      }
    }
    i2m_edt_destroy(&alone);
    i2m_image_destroy(&img);
  }
#endif
}

static const test_case_t cases[] = {
    {"feature transform exact (brute force)", test_feature_transform_exact},
    {"closest interface point", test_closest_point},
    {"image without interface", test_no_interface},
    {"segment bisection", test_bisection},
    {"connected components against a flood fill", test_components},
    {"transform in shares (2, 3, 5 parts) = alone; an error is every part's", test_shared},
};
TEST_MAIN("image oracles", cases)
