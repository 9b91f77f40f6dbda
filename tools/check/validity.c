/* i2m-check: validity of a tetrahedral mesh, recomputed from the file alone.  Vertex ids in
 * range; exact orientation of every tetrahedron; face matching by sorting (faces bucketed by
 * their smallest vertex, then sorted by the other two): each face is used once (boundary) or
 * twice (interior, by two tetrahedra on opposite sides), never three times; no dangling or
 * duplicate vertices; the boundary surface is closed; interface triangles derived from the
 * tetrahedra, compared with the file's triangles when it has some.  Either orientation of
 * the file's triangles is accepted, outward (from the higher label to the lower: out of the
 * domain on the outer boundary, what i2m writes) or inward, if the whole file agrees: a file
 * that mixes both is invalid, since no reader can tell which way its surfaces face. */
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Outward-oriented face opposite vertex f of a positive tetrahedron. */
static const int FACE[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

typedef struct {
  uint64_t key; /* (middle id << 32) | largest id */
  int64_t id;   /* (4 t + f) << 1 | the parity of the face's sorting permutation */
} fent_t;

static int cmp_fent(const void *a, const void *b)
{
  const fent_t *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return (x->id > y->id) - (x->id < y->id);
}

/* Sorted ids of a triangle and the parity (0 even, 1 odd) of the sorting permutation. */
static int sort3(int64_t v0, int64_t v1, int64_t v2, int64_t s[3])
{
  int par = 0;
  int64_t t;
  s[0] = v0, s[1] = v1, s[2] = v2;
  if (s[0] > s[1]) { t = s[0]; s[0] = s[1]; s[1] = t; par ^= 1; }
  if (s[1] > s[2]) { t = s[1]; s[1] = s[2]; s[2] = t; par ^= 1; }
  if (s[0] > s[1]) { t = s[0]; s[0] = s[1]; s[1] = t; par ^= 1; }
  return par;
}

static int face_of(const ck_mesh_t *m, int64_t id, int64_t s[3])
{
  const int64_t *tv = m->tet + 4 * (id / 4);
  const int *F = FACE[id % 4];
  return sort3(tv[F[0]], tv[F[1]], tv[F[2]], s);
}

/* qsort() of n items, none when n == 0: an empty array may be NULL (i2m_malloc of 0 bytes),
 * which qsort() and memcpy() must not be given. */
static void sort_n(void *a, int64_t n, size_t size, int (*cmp)(const void *, const void *))
{
  if (n > 0) qsort(a, (size_t)n, size, cmp);
}

void ck_validity_add_error(ck_validity_t *v, const char *name)
{
  size_t n = strlen(v->errors);
  v->valid = 0;
  if (n + strlen(name) + 2 >= sizeof v->errors) return;
  snprintf(v->errors + n, sizeof v->errors - n, "%s%s", n ? "," : "", name);
}

static void isort_fent(fent_t *a, int64_t n)
{
  for (int64_t i = 1; i < n; i++) {
    fent_t x = a[i];
    int64_t j = i - 1;
    while (j >= 0 && cmp_fent(&a[j], &x) > 0) {
      a[j + 1] = a[j];
      j--;
    }
    a[j + 1] = x;
  }
}

/* The vertices of tet t in increasing order. */
static void sorted_tet(const ck_mesh_t *m, int64_t t, int64_t q[4])
{
  const int64_t *tv = m->tet + 4 * t;
  for (int i = 0; i < 4; i++) {
    int64_t x = tv[i];
    int j = i;
    for (; j > 0 && q[j - 1] > x; j--) q[j] = q[j - 1];
    q[j] = x;
  }
}

/* A defect's count and its first case, after one more chunk (chunks taken in order): the
 * chunk's first case is the first overall when no chunk before it had one. */
static void add_defects(int64_t *count, int64_t *first, int64_t chunk_count, int64_t chunk_first)
{
  if (chunk_count && !*count) *first = chunk_first;
  *count += chunk_count;
}

/* The face counts of a range of buckets (one chunk's; chunks combine in order). */
typedef struct {
  int64_t boundary, interior, nonmanifold, first_nonmanifold, overlapping, first_overlapping;
} face_part_t;

/* Matches the faces of buckets [b0, b1) (each sorted: equal keys adjacent). */
static void match_buckets(const int8_t *sgn, const fent_t *ent, const int64_t *start, int64_t b0,
                          int64_t b1, int64_t *nb, face_part_t *c)
{
  c->first_nonmanifold = c->first_overlapping = -1;
  for (int64_t b = b0; b < b1; b++)
    for (int64_t i = start[b]; i < start[b + 1];) {
      int64_t j = i + 1;
      while (j < start[b + 1] && ent[j].key == ent[i].key) j++;
      const int64_t ea = ent[i].id, eb = ent[i + 1 < j ? i + 1 : i].id, ia = ea >> 1, ib = eb >> 1;
      if (j - i == 1) {
        nb[ia] = -1;
        c->boundary++;
      } else if (j - i == 2) {
        nb[ia] = ib;
        nb[ib] = ia;
        c->interior++;
        if (sgn[ia / 4] > 0 && sgn[ib / 4] > 0 && (ea & 1) == (eb & 1)) { /* (the same side of the face) */
          if (c->overlapping++ == 0) c->first_overlapping = ia / 4;
        }
      } else {
        for (int64_t k = i; k < j; k++) nb[ent[k].id >> 1] = -2;
        if (c->nonmanifold++ == 0) c->first_nonmanifold = ia / 4;
      }
      i = j;
    }
}

/* Face matching: fills topo->nb and the face counts.  The faces are bucketed by their smallest
 * vertex (counted and placed by the threads: the order within a bucket is then the threads',
 * and sorting each bucket by (key, face) makes it one order again). */
static i2m_err_t match_faces(const ck_mesh_t *m, const int8_t *sgn, ck_validity_t *v, ck_topo_t *topo)
{
  int64_t *start = NULL, *next = NULL;
  fent_t *ent = NULL;
  face_part_t part[CK_CHUNKS] = {{0}};
  i2m_err_t err = I2M_OK;
  const int64_t nf = 4 * m->nt, nv = m->nv;
  I2M_CALL(i2m_malloc((size_t)nf, sizeof *topo->nb, &topo->nb));
  I2M_CALL(i2m_calloc((size_t)nv + 1, sizeof *start, &start));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nv + 1, sizeof *next, &next));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nf, sizeof *ent, &ent));
  /* a tet with sorted vertices a <= b <= c <= d has three faces in bucket a and one (b c d) in
   * b (when a = b, all four in a: the fourth takes b's slot) */
  CK_OMP("omp parallel for schedule(static)")
  for (int64_t t = 0; t < m->nt; t++) {
    int64_t q[4];
    sorted_tet(m, t, q);
    CK_OMP("omp atomic")
    start[q[0] + 1] += 3;
    CK_OMP("omp atomic")
    start[q[1] + 1]++;
  }
  for (int64_t i = 0; i < nv; i++) start[i + 1] += start[i];
  memcpy(next, start, (size_t)(nv + 1) * sizeof *next);
  CK_OMP("omp parallel for schedule(static)")
  for (int64_t t = 0; t < m->nt; t++) {
    int64_t q[4], at, bt;
    sorted_tet(m, t, q);
    CK_OMP("omp atomic capture")
    { at = next[q[0]]; next[q[0]] += 3; }
    CK_OMP("omp atomic capture")
    bt = next[q[1]]++;
    for (int f = 0, in_a = 0; f < 4; f++) {
      int64_t s[3];
      const int par = face_of(m, 4 * t + f, s);
      const int64_t slot = s[0] == q[0] && in_a < 3 ? at + in_a++ : bt;
      ent[slot] = (fent_t){((uint64_t)s[1] << 32) | (uint64_t)s[2], (4 * t + f) << 1 | par};
    }
  }
  CK_OMP("omp parallel for schedule(dynamic, 4096)")
  for (int64_t b = 0; b < nv; b++) {
    int64_t n = start[b + 1] - start[b];
    if (n < 32)
      isort_fent(ent + start[b], n);
    else
      qsort(ent + start[b], (size_t)n, sizeof *ent, cmp_fent);
  }
  CK_OMP("omp parallel for schedule(dynamic, 1)")
  for (int c = 0; c < CK_CHUNKS; c++)
    match_buckets(sgn, ent, start, ck_chunk_begin(nv, c), ck_chunk_begin(nv, c + 1), topo->nb, &part[c]);
  v->first_nonmanifold_tet = v->first_overlapping_tet = -1;
  for (int c = 0; c < CK_CHUNKS; c++) {
    const face_part_t *x = &part[c];
    add_defects(&v->nonmanifold_faces, &v->first_nonmanifold_tet, x->nonmanifold, x->first_nonmanifold);
    add_defects(&v->overlapping_faces, &v->first_overlapping_tet, x->overlapping, x->first_overlapping);
    v->boundary_faces += x->boundary;
    v->interior_faces += x->interior;
  }
out:
  i2m_free(&start);
  i2m_free(&next);
  i2m_free(&ent);
  return err;
}

static int cmp_u64(const void *a, const void *b)
{
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return (x > y) - (x < y);
}

/* Every edge of the boundary surface must be used an even number of times. */
static i2m_err_t boundary_edges(const ck_mesh_t *m, const ck_topo_t *topo, ck_validity_t *v)
{
  uint64_t *e = NULL;
  int64_t ne = 0, s[3];
  I2M_CALL(i2m_malloc((size_t)v->boundary_faces * 3, sizeof *e, &e));
  for (int64_t id = 0; id < 4 * m->nt; id++) {
    if (topo->nb[id] != -1) continue;
    face_of(m, id, s);
    e[ne++] = ((uint64_t)s[0] << 32) | (uint64_t)s[1];
    e[ne++] = ((uint64_t)s[0] << 32) | (uint64_t)s[2];
    e[ne++] = ((uint64_t)s[1] << 32) | (uint64_t)s[2];
  }
  sort_n(e, ne, sizeof *e, cmp_u64);
  for (int64_t i = 0; i < ne;) {
    int64_t j = i + 1;
    while (j < ne && e[j] == e[i]) j++;
    v->boundary_edges++;
    if ((j - i) % 2) v->boundary_open_edges++;
    i = j;
  }
  i2m_free(&e);
  return I2M_OK;
}

/* Dangling (unused) and duplicate (same coordinates) vertices; duplicates by hashing. */
static i2m_err_t vertices(const ck_mesh_t *m, ck_validity_t *v)
{
  uint8_t *used = NULL;
  int64_t *slot = NULL;
  I2M_CALL(i2m_calloc((size_t)m->nv, 1, &used));
  for (int64_t i = 0; i < 4 * m->nt; i++) used[m->tet[i]] = 1;
  v->first_dangling = v->first_duplicate = v->first_duplicate_of = -1;
  for (int64_t i = 0; i < m->nv; i++)
    if (!used[i] && v->dangling++ == 0) v->first_dangling = i;
  i2m_free(&used);
  size_t cap = 16;
  while (cap < 2 * (size_t)m->nv) cap *= 2;
  I2M_CALL(i2m_malloc(cap, sizeof *slot, &slot));
  for (size_t i = 0; i < cap; i++) slot[i] = -1;
  for (int64_t i = 0; i < m->nv; i++) {
    double x[3];
    uint64_t bits[3], h = 1469598103934665603ull;
    for (int a = 0; a < 3; a++) {
      x[a] = m->xyz[3 * i + a] + 0.0; /* -0 -> +0 */
      memcpy(&bits[a], &x[a], 8);
      h = (h ^ bits[a]) * 0x100000001b3ull;
      h ^= h >> 29;
    }
    size_t s = (size_t)(h * 0x9E3779B97F4A7C15ull >> 20) & (cap - 1);
    while (slot[s] >= 0) {
      const double *y = m->xyz + 3 * slot[s];
      if (y[0] == x[0] && y[1] == x[1] && y[2] == x[2]) break;
      s = (s + 1) & (cap - 1);
    }
    if (slot[s] >= 0) {
      if (v->duplicate++ == 0) {
        v->first_duplicate = i;
        v->first_duplicate_of = slot[s];
      }
    } else {
      slot[s] = i;
    }
  }
  i2m_free(&slot);
  return I2M_OK;
}

/* Does label a rank below label b?  The background 0 ranks below every tissue, tissues by
 * value: the "outward" orientation points from the higher-ranked label to the lower, out of
 * the meshed domain on the outer boundary (the Medit / mmg / Gmsh convention). */
static int ranks_below(int64_t a, int64_t b)
{
  return a != b && (a == 0 || (b != 0 && a < b));
}

/* Face id of tet t's faces that is an interface triangle, written as the n-th triangle when
 * f->v is set (else only counted); returns whether it is one. */
static int interface_face(const ck_mesh_t *m, const ck_topo_t *topo, int64_t id, ck_iface_t *f, int64_t n)
{
  int64_t nb = topo->nb[id], lt = m->tet_label[id / 4], lo;
  if (nb == -2 || (nb >= 0 && nb < id)) return 0;
  lo = nb >= 0 ? m->tet_label[nb / 4] : 0;
  if (lo == lt) return 0;
  if (f->v) {
    const int64_t *tv = m->tet + 4 * (id / 4);
    const int *F = FACE[id % 4];
    int keep = ranks_below(lo, lt); /* the face's normal points out of this tet, to lo */
    f->v[3 * n] = (int32_t)tv[F[0]];
    f->v[3 * n + 1] = (int32_t)tv[keep ? F[1] : F[2]];
    f->v[3 * n + 2] = (int32_t)tv[keep ? F[2] : F[1]];
    f->lab[2 * n] = lt < lo ? lt : lo;
    f->lab[2 * n + 1] = lt < lo ? lo : lt;
  }
  return 1;
}

/* Interface triangles from the tetrahedra: boundary faces (label vs 0) and faces between
 * two labels, oriented outward (from the higher-ranked label to the lower), in the faces'
 * order: counted per chunk of tets, then written at each chunk's offset, on the threads. */
static i2m_err_t derive_interfaces(const ck_mesh_t *m, ck_topo_t *topo)
{
  ck_iface_t *f = &topo->iface;
  int64_t first[CK_CHUNKS + 1] = {0};
  for (int pass = 0; pass < 2; pass++) {
    if (pass == 1) {
      for (int c = 0; c < CK_CHUNKS; c++) first[c + 1] += first[c];
      f->n = first[CK_CHUNKS];
      I2M_CALL(i2m_malloc((size_t)f->n * 3, sizeof *f->v, &f->v));
      I2M_CALL(i2m_malloc((size_t)f->n * 2, sizeof *f->lab, &f->lab));
    }
    CK_OMP("omp parallel for schedule(dynamic, 1)")
    for (int c = 0; c < CK_CHUNKS; c++) {
      int64_t n = pass ? first[c] : 0;
      for (int64_t id = 4 * ck_chunk_begin(m->nt, c); id < 4 * ck_chunk_begin(m->nt, c + 1); id++)
        n += interface_face(m, topo, id, f, n);
      if (!pass) first[c + 1] = n;
    }
  }
  return I2M_OK;
}

typedef struct {
  int64_t s[3];
  int64_t a, b;
  int par;
} tkey_t;

static int cmp_tkey(const void *x, const void *y)
{
  const tkey_t *p = x, *q = y;
  for (int k = 0; k < 3; k++)
    if (p->s[k] != q->s[k]) return p->s[k] < q->s[k] ? -1 : 1;
  return 0;
}

/* The file's triangles against the derived ones: each file triangle is matched by vertex set
 * and counted as outward or inward (the derived ones are outward). */
static i2m_err_t compare_file(const ck_mesh_t *m, const ck_topo_t *topo, ck_validity_t *v)
{
  const ck_iface_t *f = &topo->iface;
  tkey_t *d = NULL, *t = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL(i2m_malloc((size_t)f->n, sizeof *d, &d));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)m->ntri, sizeof *t, &t));
  for (int64_t i = 0; i < f->n; i++) {
    d[i].par = sort3(f->v[3 * i], f->v[3 * i + 1], f->v[3 * i + 2], d[i].s);
    d[i].a = f->lab[2 * i];
    d[i].b = f->lab[2 * i + 1];
  }
  for (int64_t i = 0; i < m->ntri; i++) {
    t[i].par = sort3(m->tri[3 * i], m->tri[3 * i + 1], m->tri[3 * i + 2], t[i].s);
    t[i].a = m->tri_label[2 * i];
    t[i].b = m->tri_label[2 * i + 1];
  }
  sort_n(d, f->n, sizeof *d, cmp_tkey);
  sort_n(t, m->ntri, sizeof *t, cmp_tkey);
  int64_t i = 0, j = 0;
  while (i < f->n || j < m->ntri) {
    if (j > 0 && j < m->ntri && cmp_tkey(&t[j], &t[j - 1]) == 0) {
      v->file_duplicate++;
      j++;
      continue;
    }
    int c = i >= f->n ? 1 : j >= m->ntri ? -1 : cmp_tkey(&d[i], &t[j]);
    if (c < 0) {
      v->interface_not_in_file++;
      i++;
    } else if (c > 0) {
      v->file_not_interface++;
      j++;
    } else {
      if (m->tri_labels_known && (d[i].a != t[j].a || d[i].b != t[j].b)) v->file_label_mismatch++;
      if (d[i].par == t[j].par)
        v->file_outward++;
      else
        v->file_inward++;
      i++;
      j++;
    }
  }
out:
  i2m_free(&d);
  i2m_free(&t);
  return err;
}

static int cmp_pair(const void *x, const void *y)
{
  const int64_t *a = x, *b = y;
  if (a[0] != b[0]) return a[0] < b[0] ? -1 : 1;
  return (a[1] > b[1]) - (a[1] < b[1]);
}

/* Number of distinct label pairs among the interface triangles (runs of one pair, common in
 * the tets' order, kept once before the sort). */
static i2m_err_t count_pairs(const ck_iface_t *f, int64_t *npairs)
{
  int64_t *p = NULL, n = 0, k = 0;
  I2M_CALL(i2m_malloc((size_t)f->n * 2, sizeof *p, &p));
  for (int64_t i = 0; i < f->n; i++)
    if (k == 0 || cmp_pair(f->lab + 2 * i, p + 2 * k - 2) != 0) {
      p[2 * k] = f->lab[2 * i];
      p[2 * k + 1] = f->lab[2 * i + 1];
      k++;
    }
  sort_n(p, k, 2 * sizeof *p, cmp_pair);
  for (int64_t i = 0; i < k; i++) n += i == 0 || cmp_pair(p + 2 * i, p + 2 * i - 2) != 0;
  i2m_free(&p);
  *npairs = n;
  return I2M_OK;
}

/* The orientation figures of a range of tets (one chunk's; chunks combine in order). */
typedef struct {
  int64_t inverted, first_inverted, degenerate, first_degenerate, min_volume_tet;
  double min_volume, total_volume;
} geom_part_t;

static void geometry_range(const ck_mesh_t *m, int64_t lo, int64_t hi, ck_topo_t *topo, int8_t *sgn, geom_part_t *c)
{
  c->first_inverted = c->first_degenerate = c->min_volume_tet = -1;
  for (int64_t t = lo; t < hi; t++) {
    const int64_t *tv = m->tet + 4 * t;
    const double *a = m->xyz + 3 * tv[0], *b = m->xyz + 3 * tv[1], *cc = m->xyz + 3 * tv[2],
                 *d = m->xyz + 3 * tv[3];
    sgn[t] = (int8_t)ck_orient3d(a, b, cc, d);
    topo->vol[t] = ck_volume6(a, b, cc, d) / 6.0;
    if (sgn[t] < 0 && c->inverted++ == 0) c->first_inverted = t;
    if (sgn[t] == 0 && c->degenerate++ == 0) c->first_degenerate = t;
    if (c->min_volume_tet < 0 || topo->vol[t] < c->min_volume) {
      c->min_volume = topo->vol[t];
      c->min_volume_tet = t;
    }
    c->total_volume += topo->vol[t];
  }
}

/* Exact orientation and volume of every tet, in fixed chunks on the threads. */
static void geometry(const ck_mesh_t *m, ck_validity_t *v, ck_topo_t *topo, int8_t *sgn)
{
  geom_part_t part[CK_CHUNKS] = {{0}};
  CK_OMP("omp parallel for schedule(dynamic, 1)")
  for (int c = 0; c < CK_CHUNKS; c++)
    geometry_range(m, ck_chunk_begin(m->nt, c), ck_chunk_begin(m->nt, c + 1), topo, sgn, &part[c]);
  v->first_inverted = v->first_degenerate = v->min_volume_tet = -1;
  for (int c = 0; c < CK_CHUNKS; c++) {
    const geom_part_t *x = &part[c];
    add_defects(&v->inverted, &v->first_inverted, x->inverted, x->first_inverted);
    add_defects(&v->degenerate, &v->first_degenerate, x->degenerate, x->first_degenerate);
    if (x->min_volume_tet >= 0 && (v->min_volume_tet < 0 || x->min_volume < v->min_volume)) {
      v->min_volume = x->min_volume;
      v->min_volume_tet = x->min_volume_tet;
    }
    v->total_volume += x->total_volume;
  }
}

i2m_err_t ck_validity(const ck_mesh_t *m, ck_validity_t *v, ck_topo_t *topo) { return ck_validity_progress(m, v, topo, NULL); }

#define VALIDITY_PASSES 7 /* (the progress line's passes over the tets) */

/* Pass k of VALIDITY_PASSES done. */
static void passed(ck_progress_t *pr, const ck_mesh_t *m, int k)
{
  if (pr) ck_progress_to(pr, k * m->nt);
}

i2m_err_t ck_validity_progress(const ck_mesh_t *m, ck_validity_t *v, ck_topo_t *topo, ck_progress_t *pr)
{
  int8_t *sgn = NULL;
  if (pr) pr->p.total = VALIDITY_PASSES * m->nt;
  i2m_err_t err = I2M_OK;
  memset(v, 0, sizeof *v);
  memset(topo, 0, sizeof *topo);
  v->first_bad_index = -1;
  I2M_CHECK(m->nv < INT32_MAX, I2M_ERR_UNSUPPORTED, "%s: %lld vertices: more than 32-bit ids",
            m->path, (long long)m->nv);
  for (int64_t t = 0; t < m->nt; t++)
    for (int j = 0; j < 4; j++)
      if (m->tet[4 * t + j] < 0 || m->tet[4 * t + j] >= m->nv) {
        if (v->bad_index++ == 0) v->first_bad_index = t;
        break;
      }
  for (int64_t i = 0; i < 3 * m->ntri; i++)
    if (m->tri[i] < 0 || m->tri[i] >= m->nv) v->tri_bad_index++;
  v->first_nonfinite = -1;
  for (int64_t i = 0; i < m->nv; i++)
    if (!isfinite(m->xyz[3 * i]) || !isfinite(m->xyz[3 * i + 1]) || !isfinite(m->xyz[3 * i + 2]))
      if (v->nonfinite++ == 0) v->first_nonfinite = i;
  v->file_triangles = m->ntri;
  if (m->nt == 0) ck_validity_add_error(v, "no_tetrahedra");
  if (v->bad_index) ck_validity_add_error(v, "index_out_of_range");
  if (v->tri_bad_index) ck_validity_add_error(v, "file_triangle_index_out_of_range");
  if (v->nonfinite) ck_validity_add_error(v, "nonfinite_vertex");
  if (v->bad_index || v->nonfinite) { /* nothing else can be computed safely */
    v->valid = 0;
    return I2M_OK;
  }
  I2M_CALL(i2m_malloc((size_t)m->nt, sizeof *sgn, &sgn));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)m->nt, sizeof *topo->vol, &topo->vol));
  passed(pr, m, 1);
  geometry(m, v, topo, sgn);
  passed(pr, m, 2);
  I2M_CALL_GOTO(err, out, match_faces(m, sgn, v, topo));
  passed(pr, m, 3);
  I2M_CALL_GOTO(err, out, boundary_edges(m, topo, v));
  passed(pr, m, 4);
  I2M_CALL_GOTO(err, out, vertices(m, v));
  passed(pr, m, 5);
  I2M_CALL_GOTO(err, out, derive_interfaces(m, topo));
  v->interface_triangles = topo->iface.n;
  I2M_CALL_GOTO(err, out, count_pairs(&topo->iface, &v->interface_pairs));
  passed(pr, m, 6);
  if (m->has_tri && !v->tri_bad_index) I2M_CALL_GOTO(err, out, compare_file(m, topo, v));
  passed(pr, m, 7);
  v->file_flipped = v->file_outward < v->file_inward ? v->file_outward : v->file_inward;
  if (v->inverted) ck_validity_add_error(v, "inverted");
  if (v->degenerate) ck_validity_add_error(v, "degenerate");
  if (v->nonmanifold_faces) ck_validity_add_error(v, "nonmanifold_face");
  if (v->overlapping_faces) ck_validity_add_error(v, "overlapping");
  if (v->dangling) ck_validity_add_error(v, "dangling_vertex");
  if (v->duplicate) ck_validity_add_error(v, "duplicate_vertex");
  if (v->boundary_open_edges) ck_validity_add_error(v, "open_boundary");
  if (v->file_not_interface) ck_validity_add_error(v, "file_triangle_not_interface");
  if (v->interface_not_in_file) ck_validity_add_error(v, "interface_missing_from_file");
  if (v->file_label_mismatch) ck_validity_add_error(v, "interface_label_mismatch");
  if (v->file_duplicate) ck_validity_add_error(v, "duplicate_file_triangle");
  if (v->file_outward && v->file_inward) ck_validity_add_error(v, "mixed_triangle_orientation");
out:
  v->valid = v->errors[0] == '\0';
  i2m_free(&sgn);
  return err;
}

void ck_topo_free(ck_topo_t *t)
{
  i2m_free(&t->nb);
  i2m_free(&t->vol);
  i2m_free(&t->iface.v);
  i2m_free(&t->iface.lab);
}

const char *ck_validity_orientation(const ck_validity_t *v)
{
  if (v->file_outward && v->file_inward) return "mixed";
  if (v->file_inward) return "inward";
  return v->file_outward ? "outward" : "none";
}
