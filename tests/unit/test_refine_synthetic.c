/* Unit tests of Delaunay refinement (layer 4) on small synthetic label images: the final
 * triangulation is valid and Delaunay; every output tet meets the radius-edge bound; the
 * interface triangles meet the angle bound and carry the right label pairs; every label is
 * present with about its voxel volume; a left-handed image frame still gives positive tets;
 * runs are deterministic; bad parameters are refused with a message; the sliver
 * perturbation keeps all of this and never lowers the smallest dihedral angle; the output
 * order (tets along a curve, vertices as they first come) keeps the mesh as it was. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/geometry.h"
#include "i2m/quality.h"
#include "i2m/refine.h"
#include "test_util.h"

#define N 22

/* label(i,j,k) for the shapes */
typedef int64_t (*shape_fn)(double x, double y, double z);
static int64_t nested(double x, double y, double z)
{
  double r = sqrt(x * x + y * y + z * z);
  return r < 4.5 ? 20 : r < 8.5 ? 7 : 0;
}
static int64_t two_balls(double x, double y, double z)
{
  if ((x - 3.5) * (x - 3.5) + y * y + z * z < 30) return 5;
  if ((x + 3.5) * (x + 3.5) + y * y + z * z < 30) return 9;
  return 0;
}

static i2m_image_t *make_image(shape_fn f, const double sp[3], const double *dir)
{
  int64_t n[3] = {N, N, N};
  int64_t *v = malloc(sizeof(int64_t) * N * N * N);
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++)
        v[(k * N + j) * N + i] = f((i - N / 2 + 0.5) * sp[0], (j - N / 2 + 0.5) * sp[1], (k - N / 2 + 0.5) * sp[2]);
  double origin[3] = {10, -20, 30};
  i2m_image_t *img = NULL;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, origin, dir, v, &img) == I2M_OK);
  free(v);
  return img;
}

typedef struct {
  i2m_image_t *img;
  i2m_edt_t *edt;
  i2m_refine_t *ref;
  i2m_tetmesh_t *mesh;
} run_t;

/* Refinement, then (sliver_angle > 0) the sliver perturbation, a validity and Delaunay
 * check, and extraction. */
static void run_mesher_slivers(run_t *r, const i2m_refine_params_t *p, double sliver_angle, i2m_sliver_stats_t *st)
{
  CU_ASSERT_FATAL(i2m_edt_create(r->img, &r->edt) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_create(r->img, r->edt, p, &r->ref) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_run(r->ref) == I2M_OK);
  if (sliver_angle > 0) CU_ASSERT_FATAL(i2m_refine_perturb_slivers(r->ref, sliver_angle, st) == I2M_OK);
  i2m_err_t err = i2m_dt_check(i2m_refine_dt(r->ref), true);
  if (err) fprintf(stderr, "%s\n", i2m_error_message());
  CU_ASSERT_EQUAL_FATAL(err, I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_extract(r->ref, &r->mesh) == I2M_OK);
}

static void run_mesher(run_t *r, const i2m_refine_params_t *p) { run_mesher_slivers(r, p, 0, NULL); }

static void run_free(run_t *r)
{
  i2m_tetmesh_destroy(&r->mesh);
  i2m_refine_destroy(&r->ref);
  i2m_edt_destroy(&r->edt);
  i2m_image_destroy(&r->img);
}

/* Interface triangles point from the higher label to the lower (out of the domain on the
 * outer boundary): by the divergence theorem, each label's closed surface, its triangles
 * taken outward (the pairs where it is the higher label) and inward (where it is the lower),
 * encloses a signed volume equal to its tets' volume.  A triangle flipped the wrong way
 * changes that sum by twice its cone volume; all of them flipped negate it. */
static void check_orientation(const i2m_tetmesh_t *m)
{
  enum { MAXL = 8 };
  int64_t lab[MAXL];
  double tets[MAXL] = {0}, surface[MAXL] = {0}, total = 0;
  int nl = 0;
  for (int64_t t = 0; t < m->nt; t++) {
    int k = 0;
    while (k < nl && lab[k] != m->tet_label[t]) k++;
    if (k == nl) {
      CU_ASSERT_FATAL(nl < MAXL);
      lab[nl++] = m->tet_label[t];
    }
    const int32_t *v = m->tet + 4 * t;
    double vol = i2m_tet_signed_volume6(m->xyz + 3 * v[0], m->xyz + 3 * v[1], m->xyz + 3 * v[2], m->xyz + 3 * v[3]);
    tets[k] += vol;
    total += vol;
  }
  const double origin[3] = {0, 0, 0};
  for (int64_t f = 0; f < m->ntri; f++) {
    const int32_t *v = m->tri + 3 * f;
    double cone = i2m_tet_signed_volume6(origin, m->xyz + 3 * v[0], m->xyz + 3 * v[1], m->xyz + 3 * v[2]);
    for (int k = 0; k < nl; k++) {
      if (lab[k] == m->tri_label[2 * f + 1]) surface[k] += cone; /* the higher: outward */
      if (lab[k] == m->tri_label[2 * f]) surface[k] -= cone;
    }
  }
  CU_ASSERT(total > 0);
  for (int k = 0; k < nl; k++) CU_ASSERT(fabs(surface[k] - tets[k]) <= 1e-9 * total);
}

/* Checks the guarantees on the extracted mesh (world coordinates). */
static void check_mesh(const run_t *r, double ratio)
{
  const i2m_tetmesh_t *m = r->mesh;
  CU_ASSERT(m->nt > 100);
  i2m_quality_t q;
  CU_ASSERT_FATAL(i2m_quality_compute(m, r->img, ratio, 30, &q) == I2M_OK);
  CU_ASSERT(q.max_radius_edge <= ratio * (1 + 1e-9));
  CU_ASSERT_EQUAL(q.n_ratio_above, 0);
  CU_ASSERT(q.n_facet_below <= m->ntri / 1000);
  for (int l = 0; l < q.nlabels; l++) { /* every label present, volume within 15% */
    CU_ASSERT(q.labels[l].ntets > 0);
    CU_ASSERT(fabs(q.labels[l].volume - q.labels[l].voxel_volume) <= 0.15 * q.labels[l].voxel_volume);
  }
  i2m_quality_free(&q);
  for (int64_t t = 0; t < m->nt; t++) { /* positive volumes in the world frame */
    const int32_t *v = m->tet + 4 * t;
    CU_ASSERT(i2m_tet_signed_volume6(m->xyz + 3 * v[0], m->xyz + 3 * v[1], m->xyz + 3 * v[2], m->xyz + 3 * v[3]) > 0);
  }
  for (int64_t f = 0; f < m->ntri; f++) { /* label pairs ordered and differing */
    CU_ASSERT(m->tri_label[2 * f] < m->tri_label[2 * f + 1]);
  }
  check_orientation(m);
}

/* The nested shells at unit spacing, meshed with default parameters. */
static void run_nested(run_t *r)
{
  double sp[3] = {1, 1, 1};
  *r = (run_t){make_image(nested, sp, NULL), NULL, NULL, NULL};
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  run_mesher(r, &p);
}

static void test_nested_shells(void)
{
  run_t r;
  run_nested(&r);
  check_mesh(&r, 2.0);
  for (int64_t f = 0; f < r.mesh->ntri; f++) {
    int64_t a = r.mesh->tri_label[2 * f], b = r.mesh->tri_label[2 * f + 1];
    CU_ASSERT((a == 0 && b == 7) || (a == 7 && b == 20));
  }
  run_free(&r);
}

static void test_anisotropic_left_handed(void)
{
  double sp[3] = {0.6, 0.8, 1.4};
  double dir[9] = {-1, 0, 0, 0, 1, 0, 0, 0, 1}; /* mirrored: det -1 */
  run_t r = {make_image(nested, sp, dir), NULL, NULL, NULL};
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  run_mesher(&r, &p);
  check_mesh(&r, 2.0);
  run_free(&r);
}

static void test_touching_balls_and_ratio(void)
{
  double sp[3] = {1, 1, 1};
  run_t r = {make_image(two_balls, sp, NULL), NULL, NULL, NULL};
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  p.ratio = 2.5;
  p.size = 2.0;
  run_mesher(&r, &p);
  check_mesh(&r, 2.5);
  for (int64_t t = 0; t < r.mesh->nt; t++) { /* the size bound holds in the world frame */
    const int32_t *v = r.mesh->tet + 4 * t;
    double cc[3], r2;
    i2m_tet_circumcenter(r.mesh->xyz + 3 * v[0], r.mesh->xyz + 3 * v[1], r.mesh->xyz + 3 * v[2], r.mesh->xyz + 3 * v[3], cc, &r2);
    CU_ASSERT(sqrt(r2) <= 2.0 * (1 + 1e-9));
  }
  run_free(&r);
}

static uint64_t mesh_hash(const i2m_tetmesh_t *m)
{
  uint64_t h = 1469598103934665603ull;
  for (int64_t i = 0; i < 4 * m->nt; i++) h = (h ^ (uint64_t)m->tet[i]) * 1099511628211ull;
  for (int64_t i = 0; i < 3 * m->nv; i++) {
    uint64_t b;
    memcpy(&b, &m->xyz[i], sizeof b);
    h = (h ^ b) * 1099511628211ull;
  }
  return h;
}

static void test_deterministic(void)
{
  double sp[3] = {1, 1, 1};
  uint64_t h[2];
  for (int k = 0; k < 2; k++) {
    run_t r = {make_image(two_balls, sp, NULL), NULL, NULL, NULL};
    i2m_refine_params_t p;
    i2m_refine_params_default(&p);
    run_mesher(&r, &p);
    h[k] = mesh_hash(r.mesh);
    run_free(&r);
  }
  CU_ASSERT_EQUAL(h[0], h[1]);
}

/* The report's figures of a hand-made mesh: two tets of labels 5 and 9 on a 2x2x2 image;
 * interface triangles, one thin (below 30 degrees) whose vertex 0 is met by three label
 * pairs' triangles (a junction), one thin away from any junction. */
static void test_quality_figures(void)
{
  int64_t n[3] = {2, 2, 2}, v[8] = {5, 5, 5, 5, 9, 9, 9, 0};
  double sp[3] = {1, 1, 1};
  i2m_image_t *img = NULL;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, NULL, NULL, v, &img) == I2M_OK);
  i2m_tetmesh_t *m = NULL;
  CU_ASSERT_FATAL(i2m_tetmesh_create(9, 2, 4, &m) == I2M_OK);
  const double xyz[9][3] = {{0, 0, 0},  {1, 0, 0},  {0, 1, 0},  {0, 0, 1}, {-1, 0, 0},
                            {10, 1, 0}, {10, 0, 3}, {20, 0, 3}, {10, 1, 3}};
  memcpy(m->xyz, xyz, sizeof xyz);
  const int32_t tets[2][4] = {{0, 1, 2, 3}, {0, 2, 4, 3}}; /* unit corner tet (1/6) and its mirror (1/6) */
  memcpy(m->tet, tets, sizeof tets);
  m->tet_label[0] = 5;
  m->tet_label[1] = 9;
  const int32_t tris[4][3] = {{0, 2, 3}, {0, 1, 5}, {0, 1, 2}, {6, 7, 8}};
  const int64_t pairs[4][2] = {{5, 9}, {0, 5}, {0, 9}, {0, 9}};
  memcpy(m->tri, tris, sizeof tris);
  memcpy(m->tri_label, pairs, sizeof pairs);
  i2m_quality_t q;
  CU_ASSERT_FATAL(i2m_quality_compute(m, img, 2.0, 30.0, &q) == I2M_OK);
  /* triangles 1 and 3 are thin: 1 touches vertex 0, where pairs (5,9), (0,5), (0,9) meet */
  CU_ASSERT_EQUAL(q.n_facet_below, 2);
  CU_ASSERT_EQUAL(q.n_facet_below_junction, 1);
  CU_ASSERT_DOUBLE_EQUAL(q.min_facet_angle, atan2(1.0, 91.0) * 180.0 / I2M_PI, 1e-9); /* triangle 1 at vertex 5 */
  CU_ASSERT_EQUAL(q.n_ratio_above, 0);
  CU_ASSERT_DOUBLE_EQUAL(q.min_dihedral, acos(1.0 / sqrt(3.0)) * 180.0 / I2M_PI, 1e-9);
  CU_ASSERT_EQUAL_FATAL(q.nlabels, 2);
  for (int l = 0; l < 2; l++) {
    CU_ASSERT_EQUAL(q.labels[l].value, l == 0 ? 5 : 9);
    CU_ASSERT_EQUAL(q.labels[l].ntets, 1);
    CU_ASSERT_DOUBLE_EQUAL(q.labels[l].volume, 1.0 / 6.0, 1e-12);
    CU_ASSERT_DOUBLE_EQUAL(q.labels[l].voxel_volume, l == 0 ? 4.0 : 3.0, 1e-12);
  }
  i2m_quality_free(&q);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
}

static void test_bad_parameters(void)
{
  double sp[3] = {1, 1, 1};
  i2m_image_t *img = make_image(nested, sp, NULL);
  i2m_refine_params_t p;
  i2m_label_size_t ls = {99, 1.0};
  i2m_region_t rg = {{500, 500, 500}, {510, 510, 510}, 1.0, 2.0};
  i2m_refine_params_default(&p);
  CU_ASSERT_EQUAL(i2m_refine_params_check(&p, img), I2M_OK);
  p.ratio = 1.9;
  CU_ASSERT_EQUAL(i2m_refine_params_check(&p, img), I2M_ERR_ARG);
  i2m_refine_params_default(&p);
  p.delta = -1;
  CU_ASSERT_EQUAL(i2m_refine_params_check(&p, img), I2M_ERR_ARG);
  i2m_refine_params_default(&p);
  p.nlabel_sizes = 1;
  p.label_sizes = &ls;
  CU_ASSERT_EQUAL(i2m_refine_params_check(&p, img), I2M_ERR_ARG);
  CU_ASSERT(strstr(i2m_error_message(), "99") != NULL);
  i2m_refine_params_default(&p);
  p.nregions = 1;
  p.regions = &rg;
  CU_ASSERT_EQUAL(i2m_refine_params_check(&p, img), I2M_ERR_ARG);
  CU_ASSERT(strstr(i2m_error_message(), "outside") != NULL);
  i2m_image_destroy(&img);
  int64_t n[3] = {4, 4, 4}, zeros[64] = {0};
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, NULL, NULL, zeros, &img) == I2M_OK);
  i2m_refine_params_default(&p);
  CU_ASSERT_EQUAL(i2m_refine_params_check(&p, img), I2M_ERR_INPUT);
  i2m_image_destroy(&img);
}

/* The smallest dihedral angle of the extracted mesh. */
static double mesh_min_dihedral(const i2m_tetmesh_t *m)
{
  double amin = 180.0;
  for (int64_t t = 0; t < m->nt; t++) {
    const int32_t *v = m->tet + 4 * t;
    const double a = i2m_tet_min_dihedral(m->xyz + 3 * v[0], m->xyz + 3 * v[1], m->xyz + 3 * v[2], m->xyz + 3 * v[3]);
    amin = a < amin ? a : amin;
  }
  return amin;
}

/* Nested shells on an anisotropic grid (flat stretches of voxel faces make slivers): with the
 * perturbation at 15 degrees the mesh keeps every guarantee (valid, Delaunay, ratio, facets,
 * labels), has fewer tets below 15 degrees and a smallest angle no lower than without it, and
 * the pass's own figures agree with the mesh. */
static void test_sliver_perturbation(void)
{
  double sp[3] = {0.6, 0.8, 1.4};
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  run_t plain = {make_image(nested, sp, NULL), NULL, NULL, NULL};
  run_mesher(&plain, &p);
  const double min_plain = mesh_min_dihedral(plain.mesh);
  run_t moved = {make_image(nested, sp, NULL), NULL, NULL, NULL};
  i2m_sliver_stats_t st;
  run_mesher_slivers(&moved, &p, 15.0, &st);
  check_mesh(&moved, 2.0);
  const double min_moved = mesh_min_dihedral(moved.mesh);
  CU_ASSERT_DOUBLE_EQUAL(st.min_before, min_plain, 1e-9); /* the same refinement before the pass */
  CU_ASSERT_DOUBLE_EQUAL(st.min_after, min_moved, 1e-9);
  CU_ASSERT(st.slivers_before > 0);
  CU_ASSERT(st.slivers_after < st.slivers_before);
  CU_ASSERT(st.kept > 0 && st.kept <= st.tried);
  CU_ASSERT(min_moved >= min_plain);
  run_free(&plain);
  run_free(&moved);
}

/* Ridged shells: a ball in a thin wavy shell, in a box of another label; meshed coarsely,
 * the shell's thin ridges leave small pieces (fragments) behind. */
static int64_t ridged_shells(double x, double y, double z)
{
  const double r = sqrt(x * x + y * y + z * z), wave = 0.9 * sin(3 * atan2(y, x)) * sin(2 * acos(z / (r + 1e-12)));
  if (r < 5.0 + wave) return 4;
  if (r < 6.2 + wave) return 3;
  return fabs(x) < 9.5 && fabs(y) < 9.5 && fabs(z) < 9.5 ? 8 : 0;
}

/* Face-connected pieces of the tets of label value `value` in mesh m, counted on the mesh
 * alone: the faces sorted by their vertices, a union-find over the tets that share one. */
typedef struct {
  int32_t v[3];
  int64_t t;
} face_t;
static int cmp_face(const void *x, const void *y)
{
  const face_t *a = x, *b = y;
  for (int i = 0; i < 3; i++)
    if (a->v[i] != b->v[i]) return a->v[i] < b->v[i] ? -1 : 1;
  return 0;
}
static int64_t root_of(int64_t *par, int64_t x)
{
  while (par[x] != x) x = par[x] = par[par[x]];
  return x;
}
static int64_t mesh_pieces_of(const i2m_tetmesh_t *m, int64_t value)
{
  face_t *f = malloc(sizeof *f * 4 * (size_t)m->nt + 1);
  int64_t *par = malloc(sizeof *par * (size_t)m->nt + 1), nf = 0, pieces = 0;
  for (int64_t t = 0; t < m->nt; t++) {
    par[t] = t;
    if (m->tet_label[t] != value) continue;
    for (int i = 0; i < 4; i++) {
      face_t *e = &f[nf++];
      for (int j = 0, k = 0; j < 4; j++)
        if (j != i) e->v[k++] = m->tet[4 * t + j];
      for (int x = 0; x < 2; x++) /* (three values sorted) */
        for (int y = 0; y < 2 - x; y++)
          if (e->v[y] > e->v[y + 1]) {
            const int32_t z = e->v[y];
            e->v[y] = e->v[y + 1];
            e->v[y + 1] = z;
          }
      e->t = t;
    }
  }
  qsort(f, (size_t)nf, sizeof *f, cmp_face);
  for (int64_t k = 1; k < nf; k++)
    if (!cmp_face(&f[k - 1], &f[k])) par[root_of(par, f[k].t)] = root_of(par, f[k - 1].t);
  for (int64_t t = 0; t < m->nt; t++) pieces += m->tet_label[t] == value && root_of(par, t) == t;
  free(f);
  free(par);
  return pieces;
}

/* The census after the fragments' repair (the pieces before it, joined where fragments took a
 * neighbour's label) counts the pieces per label that the relabelled mesh has, and the
 * repair leaves every label fewer pieces. */
static void test_census_after_fragments(void)
{
  double sp[3] = {1, 1, 1};
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  p.delta = 1.5;
  run_t run = {make_image(ridged_shells, sp, NULL), NULL, NULL, NULL};
  CU_ASSERT_FATAL(i2m_edt_create(run.img, &run.edt) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_create(run.img, run.edt, &p, &run.ref) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_run(run.ref) == I2M_OK);
  i2m_label_pieces_t *before = NULL, *after = NULL;
  CU_ASSERT_FATAL(i2m_refine_census(run.ref, I2M_WHOLE_MIN_VOXELS, &before) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_repair_fragments(run.ref) == I2M_OK);
  i2m_refine_stats_t st;
  i2m_refine_get_stats(run.ref, &st);
  CU_ASSERT(st.fragments > 0); /* (else this test shows nothing) */
  CU_ASSERT_FATAL(i2m_refine_census(run.ref, I2M_WHOLE_MIN_VOXELS, &after) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_extract(run.ref, &run.mesh) == I2M_OK);
  int64_t lost = 0;
  for (int l = 1; l < run.img->nlabels; l++) {
    CU_ASSERT_EQUAL(after[l].mesh_pieces, mesh_pieces_of(run.mesh, after[l].value));
    CU_ASSERT(after[l].mesh_pieces >= 1 && after[l].mesh_pieces <= before[l].mesh_pieces);
    lost += before[l].mesh_pieces - after[l].mesh_pieces;
  }
  CU_ASSERT(lost > 0);
  free(before);
  free(after);
  run_free(&run);
}

/* Each element as a record of its vertices' coordinates (in its own vertex order) and its
 * labels, the records sorted: the mesh as a set, whatever the numbering. */
static double *element_records(const i2m_tetmesh_t *m, bool tets, int64_t *n, int *width)
{
  const int per = tets ? 4 : 3, nlab = tets ? 1 : 2;
  *n = tets ? m->nt : m->ntri;
  *width = 3 * per + nlab;
  double *rec = malloc(sizeof *rec * (size_t)(*n ? *n : 1) * (size_t)*width);
  for (int64_t e = 0; e < *n; e++) {
    double *d = rec + e * *width;
    const int32_t *v = (tets ? m->tet : m->tri) + per * e;
    for (int j = 0; j < per; j++) memcpy(d + 3 * j, m->xyz + 3 * v[j], 3 * sizeof *d);
    for (int j = 0; j < nlab; j++) d[3 * per + j] = (double)(tets ? m->tet_label[e] : m->tri_label[2 * e + j]);
  }
  return rec;
}

static int record_width;
static int cmp_record(const void *a, const void *b)
{
  const double *x = a, *y = b;
  for (int i = 0; i < record_width; i++)
    if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
  return 0;
}

static void sort_records(double *rec, int64_t n, int width)
{
  record_width = width;
  qsort(rec, (size_t)n, sizeof *rec * (size_t)width, cmp_record);
}

static int cmp_i64(const void *a, const void *b)
{
  const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x > y) - (x < y);
}

/* The median distance, in vertex numbers, between the first vertices of consecutive tets. */
static int64_t median_step(const i2m_tetmesh_t *m)
{
  int64_t *d = malloc(sizeof *d * (size_t)m->nt);
  for (int64_t t = 1; t < m->nt; t++) d[t - 1] = llabs((int64_t)m->tet[4 * t] - m->tet[4 * (t - 1)]);
  qsort(d, (size_t)(m->nt - 1), sizeof *d, cmp_i64);
  const int64_t med = d[(m->nt - 1) / 2];
  free(d);
  return med;
}

/* The output order: tets along a space-filling curve, vertices numbered as they first come,
 * triangles along the curve too; the same tets (vertex order, hence orientation, kept) and
 * triangles with their labels, and every guarantee still checked. */
static void test_output_order(void)
{
  run_t r;
  run_nested(&r);
  i2m_tetmesh_t *m = r.mesh;
  int64_t nt, nf;
  int wt, wf;
  double *t0 = element_records(m, true, &nt, &wt), *f0 = element_records(m, false, &nf, &wf);
  const int64_t nv = m->nv, step0 = median_step(m);
  CU_ASSERT_FATAL(i2m_tetmesh_sort(m) == I2M_OK);
  CU_ASSERT_EQUAL(m->nv, nv);
  double *t1 = element_records(m, true, &nt, &wt), *f1 = element_records(m, false, &nf, &wf);
  sort_records(t0, nt, wt);
  sort_records(t1, nt, wt);
  sort_records(f0, nf, wf);
  sort_records(f1, nf, wf);
  CU_ASSERT(memcmp(t0, t1, sizeof *t0 * (size_t)nt * (size_t)wt) == 0);
  CU_ASSERT(memcmp(f0, f1, sizeof *f0 * (size_t)nf * (size_t)wf) == 0);
  int32_t next = 0; /* vertices numbered as the tets first use them */
  bool first_use = true;
  for (int64_t i = 0; i < 4 * m->nt; i++) {
    if (m->tet[i] > next) first_use = false;
    if (m->tet[i] == next) next++;
  }
  CU_ASSERT(first_use);
  CU_ASSERT_EQUAL(next, m->nv);
  const int64_t step1 = median_step(m);
  CU_ASSERT(step1 * 20 < m->nv);
  CU_ASSERT(step1 <= step0);
  check_mesh(&r, 2.0);
  free(t0);
  free(t1);
  free(f0);
  free(f1);
  run_free(&r);
}

static const test_case_t cases[] = {
    {"nested shells", test_nested_shells},
    {"anisotropic, left-handed frame", test_anisotropic_left_handed},
    {"touching balls, ratio 2.5, size bound", test_touching_balls_and_ratio},
    {"deterministic", test_deterministic},
    {"bad parameters refused", test_bad_parameters},
    {"quality figures of a hand-made mesh", test_quality_figures},
    {"sliver perturbation", test_sliver_perturbation},
    {"census after the fragments' repair", test_census_after_fragments},
    {"output order along a curve", test_output_order},
};
TEST_MAIN("refinement", cases)
