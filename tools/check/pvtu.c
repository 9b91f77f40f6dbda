/* i2m-check: a distributed mesh written as a .pvtu (one .vtu piece per rank) read as one mesh.
 * The pieces are read one after the other with the VTU reader and stitched strictly by their
 * point data GlobalNodeId (a hash map global id -> stitched vertex): the vertices on the seams
 * between pieces are one id in two or more pieces.  Stitching errors, each of which makes the
 * stitched mesh invalid:
 *   (a) one global id with different coordinates in two pieces (compared bit for bit);
 *   (b) two global ids at one point (exact coordinates, hashed);
 *   (c) a piece without GlobalNodeId: its vertices are kept apart, since pieces are never
 *       stitched by coordinates;
 *   (d) a face seen by one side only: a boundary face of the stitched mesh whose three
 *       vertices are on seams and whose outer side another piece meshes (a point a small step
 *       outside the face's centroid lies in a tet of another piece).  The probe points are
 *       bucketed in a uniform grid (ck_grid_t); each tet visits the cells its box covers.
 * Part of the checker tool (no libi2m layer); memory and time linear in the mesh size. */
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ================================ stitching ==================================== */

typedef struct {
  ck_mesh_t *m;          /* borrowed: the stitched mesh being built */
  ck_stitch_t *st;       /* borrowed: m->stitch */
  int64_t vcap, tcap;    /* capacities of the stitched vertex and tet arrays */
  int64_t *slot;         /* owned: [cap] global id map, a stitched vertex k (key m->gid[k])
                            or -1 for an empty slot; open addressing, linear probing */
  size_t cap;            /* a power of two, at least twice the ids it holds */
  int32_t *first_piece;  /* owned: [vcap] the piece that brought each stitched vertex */
  int32_t *last_piece;   /* owned: [vcap] the last piece that held it (pieces counted once) */
} stitcher_t;

static size_t hash_u64(uint64_t x)
{
  /* a 64-bit finaliser: consecutive ids spread over the whole table */
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdull;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ull;
  x ^= x >> 33;
  return (size_t)x;
}

/* Capacity for at least need items, grown geometrically (0 when need is 0). */
static int64_t grown(int64_t cap, int64_t need)
{
  if (need <= cap) return cap;
  int64_t c = cap < 1024 ? 1024 : 2 * cap;
  return c < need ? need : c;
}

static i2m_err_t reserve_vertices(stitcher_t *b, int64_t need)
{
  int64_t c = grown(b->vcap, need);
  if (c == b->vcap) return I2M_OK;
  size_t n = (size_t)c;
  I2M_CALL(i2m_realloc(3 * n, sizeof *b->m->xyz, &b->m->xyz));
  I2M_CALL(i2m_realloc(n, sizeof *b->m->gid, &b->m->gid));
  I2M_CALL(i2m_realloc(n, sizeof *b->st->vert_pieces, &b->st->vert_pieces));
  I2M_CALL(i2m_realloc(n, sizeof *b->first_piece, &b->first_piece));
  I2M_CALL(i2m_realloc(n, sizeof *b->last_piece, &b->last_piece));
  b->vcap = c;
  return I2M_OK;
}

static i2m_err_t reserve_tets(stitcher_t *b, int64_t need)
{
  int64_t c = grown(b->tcap, need);
  if (c == b->tcap) return I2M_OK;
  I2M_CALL(i2m_realloc(4 * (size_t)c, sizeof *b->m->tet, &b->m->tet));
  I2M_CALL(i2m_realloc((size_t)c, sizeof *b->m->tet_label, &b->m->tet_label));
  b->tcap = c;
  return I2M_OK;
}

/* The slot of global id g: the one holding it, or the empty one where it goes. */
static size_t map_slot(const stitcher_t *b, int64_t g)
{
  size_t s = hash_u64((uint64_t)g) & (b->cap - 1);
  while (b->slot[s] >= 0 && b->m->gid[b->slot[s]] != g) s = (s + 1) & (b->cap - 1);
  return s;
}

/* Makes room for ids ids in the map (load at most 1/2), moving what it holds. */
static i2m_err_t map_reserve(stitcher_t *b, int64_t ids)
{
  size_t cap = b->cap ? b->cap : 1024;
  while (cap < 2 * (size_t)ids) cap *= 2;
  if (cap == b->cap) return I2M_OK;
  int64_t *old = b->slot;
  size_t old_cap = b->cap;
  I2M_CALL(i2m_malloc(cap, sizeof *b->slot, &b->slot));
  for (size_t s = 0; s < cap; s++) b->slot[s] = -1;
  b->cap = cap;
  for (size_t s = 0; s < old_cap; s++)
    if (old[s] >= 0) b->slot[map_slot(b, b->m->gid[old[s]])] = old[s];
  i2m_free(&old);
  return I2M_OK;
}

static int64_t add_vertex(stitcher_t *b, const double *x, int64_t gid, int piece)
{
  int64_t k = b->m->nv++;
  memcpy(b->m->xyz + 3 * k, x, 3 * sizeof *x);
  b->m->gid[k] = gid;
  b->st->vert_pieces[k] = 1;
  b->first_piece[k] = b->last_piece[k] = piece;
  return k;
}

/* (a): vertex i of piece p has the global id of stitched vertex k, at another point. */
static void coordinate_mismatch(stitcher_t *b, const ck_mesh_t *piece, int64_t i, int p, int64_t k)
{
  ck_stitch_t *st = b->st;
  const double *x = b->m->xyz + 3 * k, *y = piece->xyz + 3 * i;
  if (st->coordinate_mismatches++ > 0) return;
  snprintf(st->first_mismatch, sizeof st->first_mismatch,
           "global id %lld is at (%.17g, %.17g, %.17g) in piece %d (%s) but at (%.17g, %.17g, "
           "%.17g) in piece %d (%s)", (long long)b->m->gid[k], x[0], x[1], x[2],
           b->first_piece[k], st->piece_path[b->first_piece[k]], y[0], y[1], y[2], p,
           st->piece_path[p]);
}

/* (c): the vertices of a piece without global ids stay apart from every other. */
static void piece_without_ids(stitcher_t *b, const ck_mesh_t *piece, int p, int64_t *loc)
{
  ck_stitch_t *st = b->st;
  if (piece->nv > 0 && st->pieces_without_ids++ == 0)
    snprintf(st->first_without_ids, sizeof st->first_without_ids,
             "piece %d (%s) has no GlobalNodeId point data: it cannot be stitched (pieces are "
             "never stitched by coordinates); its %lld vertices are kept apart", p,
             st->piece_path[p], (long long)piece->nv);
  for (int64_t i = 0; i < piece->nv; i++) loc[i] = add_vertex(b, piece->xyz + 3 * i, -1, p);
}

/* The piece's vertices into the stitched mesh: loc[i] (of [piece->nv]) their new index. */
static i2m_err_t stitch_vertices(stitcher_t *b, const ck_mesh_t *piece, int p, int64_t *loc)
{
  ck_mesh_t *m = b->m;
  I2M_CALL(reserve_vertices(b, m->nv + piece->nv));
  if (!piece->has_gid) {
    piece_without_ids(b, piece, p, loc);
    return I2M_OK;
  }
  I2M_CALL(map_reserve(b, m->nv + piece->nv));
  for (int64_t i = 0; i < piece->nv; i++) {
    size_t s = map_slot(b, piece->gid[i]);
    if (b->slot[s] < 0) {
      b->slot[s] = loc[i] = add_vertex(b, piece->xyz + 3 * i, piece->gid[i], p);
      continue;
    }
    int64_t k = loc[i] = b->slot[s];
    if (memcmp(m->xyz + 3 * k, piece->xyz + 3 * i, 3 * sizeof(double)) != 0)
      coordinate_mismatch(b, piece, i, p, k);
    if (b->last_piece[k] != p) {
      b->last_piece[k] = p;
      b->st->vert_pieces[k]++;
    }
  }
  return I2M_OK;
}

/* The piece's tets, renumbered; an id out of the piece's range becomes -1 (validity
 * reports it). */
static i2m_err_t stitch_tets(stitcher_t *b, const ck_mesh_t *piece, const int64_t *loc)
{
  ck_mesh_t *m = b->m;
  I2M_CALL(reserve_tets(b, m->nt + piece->nt));
  for (int64_t i = 0; i < 4 * piece->nt; i++) {
    int64_t v = piece->tet[i];
    m->tet[4 * m->nt + i] = v >= 0 && v < piece->nv ? loc[v] : -1;
  }
  for (int64_t t = 0; t < piece->nt; t++) m->tet_label[m->nt + t] = piece->tet_label[t];
  m->nt += piece->nt;
  m->ignored_cells += piece->ignored_cells;
  return I2M_OK;
}

static int is_vtu(const char *s)
{
  size_t n = strlen(s);
  return n >= 4 && strcasecmp(s + n - 4, ".vtu") == 0;
}

/* Reads piece p; an error names the .pvtu and the piece (a missing file, a corrupt one). */
static i2m_err_t read_piece(const char *pvtu, const ck_stitch_t *st, int p, ck_mesh_t *piece)
{
  const char *file = st->piece_path[p];
  memset(piece, 0, sizeof *piece);
  I2M_CHECK(is_vtu(file), I2M_ERR_UNSUPPORTED, "%s: piece %d of %d (%s) is not a .vtu file",
            pvtu, p, st->npieces, file);
  i2m_err_t err = ck_mesh_read(file, piece);
  if (err == I2M_OK) return I2M_OK;
  char msg[1024];
  snprintf(msg, sizeof msg, "%s", i2m_error_message());
  return I2M_ERROR(err, "%s: piece %d of %d: %s", pvtu, p, st->npieces, msg);
}

static i2m_err_t stitch_piece(stitcher_t *b, const ck_mesh_t *piece, int p)
{
  int64_t *loc = NULL;
  i2m_err_t err = i2m_malloc((size_t)piece->nv, sizeof *loc, &loc);
  if (err == I2M_OK) err = stitch_vertices(b, piece, p, loc);
  if (err == I2M_OK) err = stitch_tets(b, piece, loc);
  i2m_free(&loc);
  b->st->piece_nv[p] = piece->nv;
  b->st->piece_has_gid[p] = (int8_t)piece->has_gid;
  b->st->tet_start[p + 1] = b->m->nt;
  b->st->vertices_before += piece->nv;
  return err;
}

/* Hash of a point's exact coordinates (-0 as +0: they are the same point). */
static size_t hash_point(const double *x)
{
  uint64_t h = 0;
  for (int a = 0; a < 3; a++) {
    double c = x[a] + 0.0;
    uint64_t bits;
    memcpy(&bits, &c, sizeof bits);
    h = hash_u64(h ^ bits);
  }
  return (size_t)h;
}

static int same_point(const double *x, const double *y)
{
  return x[0] == y[0] && x[1] == y[1] && x[2] == y[2];
}

/* (b): two stitched vertices with global ids at one point (they cannot share an id). */
static i2m_err_t shared_points(stitcher_t *b)
{
  const ck_mesh_t *m = b->m;
  ck_stitch_t *st = b->st;
  int64_t *slot = NULL;
  size_t cap = 1024;
  while (cap < 2 * (size_t)m->nv) cap *= 2;
  I2M_CALL(i2m_malloc(cap, sizeof *slot, &slot));
  for (size_t s = 0; s < cap; s++) slot[s] = -1;
  for (int64_t k = 0; k < m->nv; k++) {
    if (!st->piece_has_gid[b->first_piece[k]]) continue; /* (c) reports these */
    const double *x = m->xyz + 3 * k;
    size_t s = hash_point(x) & (cap - 1);
    while (slot[s] >= 0 && !same_point(m->xyz + 3 * slot[s], x)) s = (s + 1) & (cap - 1);
    if (slot[s] < 0) {
      slot[s] = k;
      continue;
    }
    int64_t j = slot[s];
    if (st->shared_points++ == 0)
      snprintf(st->first_shared, sizeof st->first_shared,
               "global ids %lld (piece %d, %s) and %lld (piece %d, %s) are at the same point "
               "(%.17g, %.17g, %.17g)", (long long)m->gid[j], b->first_piece[j],
               st->piece_path[b->first_piece[j]], (long long)m->gid[k], b->first_piece[k],
               st->piece_path[b->first_piece[k]], x[0], x[1], x[2]);
  }
  i2m_free(&slot);
  return I2M_OK;
}

static i2m_err_t stitch_create(ck_mesh_t *m, char **pieces, int n)
{
  ck_stitch_t *st = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *st, &st));
  m->stitch = st;
  st->npieces = n;
  st->piece_path = pieces; /* transferred */
  I2M_CALL(i2m_calloc((size_t)n, sizeof *st->piece_nv, &st->piece_nv));
  I2M_CALL(i2m_calloc((size_t)n + 1, sizeof *st->tet_start, &st->tet_start));
  I2M_CALL(i2m_calloc((size_t)n, sizeof *st->piece_has_gid, &st->piece_has_gid));
  return I2M_OK;
}

void ck_stitch_free(ck_stitch_t **st)
{
  if (!*st) return;
  ck_pvtu_pieces_free(&(*st)->piece_path, (*st)->npieces);
  i2m_free(&(*st)->piece_nv);
  i2m_free(&(*st)->tet_start);
  i2m_free(&(*st)->piece_has_gid);
  i2m_free(&(*st)->vert_pieces);
  i2m_free(st);
}

/* Every piece read and stitched in turn (one piece in memory beside the stitched mesh). */
static i2m_err_t stitch_all(const char *path, stitcher_t *b)
{
  for (int p = 0; p < b->st->npieces; p++) {
    ck_mesh_t piece;
    I2M_CALL(read_piece(path, b->st, p, &piece));
    i2m_err_t err = stitch_piece(b, &piece, p);
    ck_mesh_free(&piece);
    I2M_CALL(err);
  }
  for (int64_t k = 0; k < b->m->nv; k++) b->st->seam_vertices += b->st->vert_pieces[k] >= 2;
  return shared_points(b);
}

i2m_err_t ck_pvtu_read(const char *path, ck_mesh_t *m)
{
  char **pieces = NULL;
  int n = 0;
  stitcher_t b;
  memset(m, 0, sizeof *m);
  memset(&b, 0, sizeof b);
  strcpy(m->format, "pvtu");
  m->path = path;
  I2M_CALL(ck_pvtu_pieces(path, &pieces, &n));
  i2m_err_t err = stitch_create(m, pieces, n);
  if (err != I2M_OK && !m->stitch) ck_pvtu_pieces_free(&pieces, n);
  b.m = m;
  b.st = m->stitch;
  if (err == I2M_OK) err = stitch_all(path, &b);
  i2m_free(&b.slot);
  i2m_free(&b.first_piece);
  i2m_free(&b.last_piece);
  if (err != I2M_OK) ck_mesh_free(m);
  return err;
}

/* ======================== (d) faces seen by one side only ======================= */

typedef struct {
  double q[3];   /* a point a small step outside the face */
  int64_t face;  /* 4 t + f: the face opposite vertex f of stitched tet t */
  int32_t piece; /* the piece of tet t */
} probe_t;

static double dist2(const double *x, const double *y)
{
  double d[3] = {x[0] - y[0], x[1] - y[1], x[2] - y[2]};
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

/* Probe of the face opposite vertex f of tet t: its centroid moved 1e-6 of its longest edge
 * along the normal pointing away from vertex f.  0 for a face of zero area. */
static int face_probe(const ck_mesh_t *m, int64_t t, int f, probe_t *pr)
{
  const double *v[4], *a, *b, *c;
  for (int j = 0; j < 4; j++) v[j] = m->xyz + 3 * m->tet[4 * t + j];
  a = v[(f + 1) % 4], b = v[(f + 2) % 4], c = v[(f + 3) % 4];
  double u[3], w[3], n[3], cen[3], out = 0, nn = 0, longest;
  for (int k = 0; k < 3; k++) {
    u[k] = b[k] - a[k];
    w[k] = c[k] - a[k];
    cen[k] = (a[k] + b[k] + c[k]) / 3.0;
  }
  n[0] = u[1] * w[2] - u[2] * w[1];
  n[1] = u[2] * w[0] - u[0] * w[2];
  n[2] = u[0] * w[1] - u[1] * w[0];
  for (int k = 0; k < 3; k++) {
    out += n[k] * (v[f][k] - cen[k]);
    nn += n[k] * n[k];
  }
  longest = fmax(dist2(a, b), fmax(dist2(b, c), dist2(c, a)));
  if (!(nn > 0)) return 0;
  double step = 1e-6 * sqrt(longest) / sqrt(nn) * (out > 0 ? -1.0 : 1.0);
  for (int k = 0; k < 3; k++) pr->q[k] = cen[k] + step * n[k];
  pr->face = 4 * t + f;
  return 1;
}

static int seam_face(const ck_mesh_t *m, int64_t t, int f)
{
  for (int j = 1; j < 4; j++)
    if (m->stitch->vert_pieces[m->tet[4 * t + (f + j) % 4]] < 2) return 0;
  return 1;
}

/* Probes of the boundary faces with three seam vertices; *probes owned by the caller. */
static i2m_err_t collect_probes(const ck_mesh_t *m, const ck_topo_t *topo, probe_t **probes,
                                int64_t *n)
{
  const ck_stitch_t *st = m->stitch;
  *n = 0;
  for (int pass = 0; pass < 2; pass++) {
    if (pass == 1) I2M_CALL(i2m_malloc((size_t)*n, sizeof **probes, probes));
    int64_t k = 0;
    for (int p = 0; p < st->npieces; p++)
      for (int64_t t = st->tet_start[p]; t < st->tet_start[p + 1]; t++)
        for (int f = 0; f < 4; f++) {
          if (topo->nb[4 * t + f] != -1 || !seam_face(m, t, f)) continue;
          probe_t pr;
          if (!face_probe(m, t, f, &pr)) continue;
          pr.piece = p;
          if (pass == 1) (*probes)[k] = pr;
          k++;
        }
    *n = k;
  }
  return I2M_OK;
}

/* Cell edge giving about `target` cells: the volume per cell over the axes longer than a cell
 * (a plane of probes, as on a flat seam, gets a plane of cells). */
static double cell_size(const double e[3], double target)
{
  int active[3];
  double s = 1.0;
  for (int a = 0; a < 3; a++) active[a] = e[a] > 0;
  for (int it = 0; it < 3; it++) {
    double prod = 1;
    int k = 0, changed = 0;
    for (int a = 0; a < 3; a++) {
      if (!active[a]) continue;
      prod *= e[a];
      k++;
    }
    if (k == 0) return s; /* all probes at one point */
    s = pow(prod / target, 1.0 / k);
    for (int a = 0; a < 3; a++) {
      if (!active[a] || e[a] >= s) continue;
      active[a] = 0;
      changed = 1;
    }
    if (!changed) break;
  }
  return s > 0 ? s : 1.0;
}

static void probe_box(const void *ctx, int64_t k, double lo[3], double hi[3])
{
  const probe_t *pr = ctx;
  memcpy(lo, pr[k].q, 3 * sizeof *lo);
  memcpy(hi, pr[k].q, 3 * sizeof *hi);
}

/* The probes in a uniform grid of about one cell per probe over their bounding box. */
static i2m_err_t probe_grid(const probe_t *pr, int64_t np, ck_grid_t *g, double hi[3])
{
  double e[3];
  for (int a = 0; a < 3; a++) {
    g->lo[a] = hi[a] = pr[0].q[a];
    for (int64_t k = 1; k < np; k++) {
      if (pr[k].q[a] < g->lo[a]) g->lo[a] = pr[k].q[a];
      if (pr[k].q[a] > hi[a]) hi[a] = pr[k].q[a];
    }
    e[a] = hi[a] - g->lo[a];
  }
  double h = cell_size(e, (double)np);
  for (int a = 0; a < 3; a++) {
    double c = e[a] / h;
    g->h[a] = h;
    g->n[a] = c < 1e6 ? (int64_t)c + 1 : 1000000; /* (a guard: cell_size keeps it small) */
  }
  return ck_grid_build(g, np, probe_box, pr, NULL);
}

/* Is q in the closed tet t (exact orientations; a flat tet holds nothing)? */
static int tet_contains(const ck_mesh_t *m, int64_t t, const double q[3])
{
  const double *v[4];
  for (int j = 0; j < 4; j++) v[j] = m->xyz + 3 * m->tet[4 * t + j];
  int s = ck_orient3d(v[0], v[1], v[2], v[3]);
  if (s == 0) return 0;
  for (int j = 0; j < 4; j++) {
    const double *w[4] = {v[0], v[1], v[2], v[3]};
    w[j] = q;
    if (ck_orient3d(w[0], w[1], w[2], w[3]) == -s) return 0;
  }
  return 1;
}

static void tet_box(const ck_mesh_t *m, int64_t t, double lo[3], double hi[3])
{
  for (int a = 0; a < 3; a++) lo[a] = hi[a] = m->xyz[3 * m->tet[4 * t] + a];
  for (int j = 1; j < 4; j++)
    for (int a = 0; a < 3; a++) {
      double x = m->xyz[3 * m->tet[4 * t + j] + a];
      if (x < lo[a]) lo[a] = x;
      if (x > hi[a]) hi[a] = x;
    }
}

static int in_box(const double q[3], const double lo[3], const double hi[3])
{
  return q[0] >= lo[0] && q[0] <= hi[0] && q[1] >= lo[1] && q[1] <= hi[1] && q[2] >= lo[2] &&
         q[2] <= hi[2];
}

/* Looks for the probes of other pieces in tet t of piece p: hit[k] = t for the first found.
 * ghi: the upper corner of the probes' box. */
static void probe_tet(const ck_mesh_t *m, const ck_grid_t *g, const double ghi[3],
                      const probe_t *pr, int64_t t, int p, int64_t *hit)
{
  double lo[3], hi[3];
  int64_t c0[3], c1[3];
  tet_box(m, t, lo, hi);
  for (int a = 0; a < 3; a++) {
    if (hi[a] < g->lo[a] || lo[a] > ghi[a]) return;
    c0[a] = ck_grid_cell(g, a, lo[a]);
    c1[a] = ck_grid_cell(g, a, hi[a]);
  }
  for (int64_t k = c0[2]; k <= c1[2]; k++)
    for (int64_t j = c0[1]; j <= c1[1]; j++)
      for (int64_t i = c0[0]; i <= c1[0]; i++) {
        int64_t c = (k * g->n[1] + j) * g->n[0] + i;
        for (int64_t s = g->start[c]; s < g->start[c + 1]; s++) {
          int64_t q = g->item[s];
          if (pr[q].piece == p || hit[q] >= 0 || !in_box(pr[q].q, lo, hi)) continue;
          if (tet_contains(m, t, pr[q].q)) hit[q] = t;
        }
      }
}

static int piece_of_tet(const ck_stitch_t *st, int64_t t)
{
  int p = 0;
  while (p + 1 < st->npieces && st->tet_start[p + 1] <= t) p++;
  return p;
}

/* Counts the hits; the first one (in tet order) into st->first_one_sided. */
static void one_sided_report(const ck_mesh_t *m, const probe_t *pr, int64_t np, const int64_t *hit)
{
  ck_stitch_t *st = m->stitch;
  for (int64_t k = 0; k < np; k++) {
    if (hit[k] < 0 || st->one_sided_faces++ > 0) continue;
    int64_t t = pr[k].face / 4, u = hit[k];
    int f = (int)(pr[k].face % 4), p = pr[k].piece, q = piece_of_tet(st, u);
    const int64_t *tv = m->tet + 4 * t;
    snprintf(st->first_one_sided, sizeof st->first_one_sided,
             "the face of global ids %lld %lld %lld (tet %lld of piece %d, %s) is on the "
             "boundary of the stitched mesh, but its outer side lies in tet %lld of piece %d "
             "(%s): the two pieces do not share this face",
             (long long)m->gid[tv[(f + 1) % 4]], (long long)m->gid[tv[(f + 2) % 4]],
             (long long)m->gid[tv[(f + 3) % 4]], (long long)(t - st->tet_start[p]), p,
             st->piece_path[p], (long long)(u - st->tet_start[q]), q, st->piece_path[q]);
  }
}

static i2m_err_t one_sided_faces(const ck_mesh_t *m, const ck_topo_t *topo)
{
  ck_stitch_t *st = m->stitch;
  probe_t *pr = NULL;
  int64_t np = 0, *hit = NULL;
  ck_grid_t g;
  double ghi[3];
  memset(&g, 0, sizeof g);
  i2m_err_t err = collect_probes(m, topo, &pr, &np);
  st->seams_checked = 1;
  st->seam_boundary_faces = np;
  if (err != I2M_OK || np == 0) goto out;
  I2M_CALL_GOTO(err, out, probe_grid(pr, np, &g, ghi));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)np, sizeof *hit, &hit));
  for (int64_t k = 0; k < np; k++) hit[k] = -1;
  for (int p = 0; p < st->npieces; p++)
    for (int64_t t = st->tet_start[p]; t < st->tet_start[p + 1]; t++)
      probe_tet(m, &g, ghi, pr, t, p, hit);
  one_sided_report(m, pr, np, hit);
out:
  i2m_free(&pr);
  i2m_free(&hit);
  ck_grid_free(&g);
  return err;
}

i2m_err_t ck_stitch_check(const ck_mesh_t *m, const ck_topo_t *topo, ck_validity_t *v)
{
  const ck_stitch_t *st = m->stitch;
  if (!st) return I2M_OK;
  if (topo->nb) I2M_CALL(one_sided_faces(m, topo)); /* (else ids out of range or NaNs) */
  if (st->coordinate_mismatches) ck_validity_add_error(v, "stitch_coordinate_mismatch");
  if (st->shared_points) ck_validity_add_error(v, "stitch_shared_point");
  if (st->pieces_without_ids) ck_validity_add_error(v, "stitch_no_global_ids");
  if (st->one_sided_faces) ck_validity_add_error(v, "stitch_one_sided_face");
  return I2M_OK;
}
