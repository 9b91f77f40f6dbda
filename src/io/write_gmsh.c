/* io layer: Gmsh writer (.msh): MSH 4.1 (the default) or 2.2, binary by default, ASCII when
 * asked (i2m_write_opts_t.ascii, or the environment variable I2M_MSH_ASCII=1).  One volume
 * entity per tetrahedron label (physical tag = the label value, physical name = the tissue
 * name when the options carry one, else "label_<v>"), one surface entity per interface label
 * pair (physical tag = largest label + 1 + pair number, name "interface_<a>_<b>": the label
 * values, so that the pair is known whatever the tissue names), all nodes in one block, one
 * element block per entity (type 4 tetrahedra, type 2 triangles).  In 4.1 every volume entity
 * lists its bounding surfaces: the interface surfaces that touch its label, positive when
 * their triangles' normals point out of the volume.  MSH 2.2 has no entities: each element
 * carries its physical and elementary tags.  Binary data is little-endian (4.1: 8-byte
 * size_t; 2.2: 4-byte ints, so at most 2^31 - 1 nodes and elements). */
#include "io_impl.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
  io_out_t o;
  int ascii;
  int v22;   /* MSH 2.2 instead of 4.1 */
} gm_t;

/* Longest physical name written (bytes; Gmsh's own limit is 256). */
#define GM_NAME_MAX 127

static void gm_size(gm_t *g, uint64_t v)
{
  char *p = io_out_reserve(&g->o, 32);
  if (!p) return;
  if (g->ascii) {
    int k = io_fmt_i64(p, (int64_t)v);
    p[k++] = ' ';
    io_out_commit(&g->o, (size_t)k);
  } else {
    io_le64(p, v);
    io_out_commit(&g->o, 8);
  }
}

static void gm_int(gm_t *g, int32_t v)
{
  char *p = io_out_reserve(&g->o, 32);
  if (!p) return;
  if (g->ascii) {
    int k = io_fmt_i64(p, v);
    p[k++] = ' ';
    io_out_commit(&g->o, (size_t)k);
  } else {
    io_le32(p, (uint32_t)v);
    io_out_commit(&g->o, 4);
  }
}

static void gm_dbl(gm_t *g, double v)
{
  char *p = io_out_reserve(&g->o, 64);
  if (!p) return;
  if (g->ascii) {
    int k = snprintf(p, 64, "%.17g ", v);
    io_out_commit(&g->o, (size_t)k);
  } else {
    uint64_t bits;
    memcpy(&bits, &v, 8);
    io_le64(p, bits);
    io_out_commit(&g->o, 8);
  }
}

static void gm_eol(gm_t *g)
{
  if (g->ascii) io_out_put(&g->o, "\n", 1);
}

/* Entities: L volumes (labels) and P surfaces (pairs), with their elements in order. */
typedef struct {
  int64_t nlab, npair;
  int64_t *lab;      /* owned: [nlab] distinct tetrahedron labels, increasing */
  int64_t *pairs;    /* owned: [npair][2] */
  int32_t *tri_pair; /* owned: [ntri] */
  int64_t *tstart;   /* owned: [nlab+1] first position in torder of each label */
  int64_t *torder;   /* owned: [nt] tetrahedra grouped by label */
  int64_t *fstart;   /* owned: [npair+1] */
  int64_t *forder;   /* owned: [ntri] triangles grouped by pair */
  double *box;       /* owned: [nlab+npair][6] bounding boxes */
  int32_t surf_tag0; /* physical tag of pair 0 */
  int64_t *bstart;   /* owned: [nlab+1] first position in bsurf of each volume's surfaces */
  int32_t *bsurf;    /* owned: [2 npair] bounding surface entity tags, signed by orientation */
  char **vol_name;   /* owned: [nlab] physical names of the volumes, each owned */
} gm_ent_t;

static void gm_ent_free(gm_ent_t *e)
{
  i2m_free(&e->lab);
  i2m_free(&e->pairs);
  i2m_free(&e->tri_pair);
  i2m_free(&e->tstart);
  i2m_free(&e->torder);
  i2m_free(&e->fstart);
  i2m_free(&e->forder);
  i2m_free(&e->box);
  i2m_free(&e->bstart);
  i2m_free(&e->bsurf);
  for (int64_t l = 0; e->vol_name && l < e->nlab; l++) i2m_free(&e->vol_name[l]);
  i2m_free(&e->vol_name);
}

static int64_t find_label(const gm_ent_t *e, int64_t v)
{
  int64_t lo = 0, hi = e->nlab - 1;
  while (lo < hi) {
    int64_t mid = (lo + hi) / 2;
    if (e->lab[mid] < v)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

static void box_add(double *b, const double *x)
{
  for (int a = 0; a < 3; a++) {
    if (x[a] < b[a]) b[a] = x[a];
    if (x[a] > b[3 + a]) b[3 + a] = x[a];
  }
}

/* Groups n items (ids given by key()) into buckets by counting sort. */
static i2m_err_t group(int64_t n, int64_t nb, const int64_t *key, int64_t **start, int64_t **order)
{
  I2M_CALL(i2m_calloc((size_t)nb + 1, sizeof **start, start));
  I2M_CALL(i2m_malloc((size_t)n, sizeof **order, order));
  for (int64_t i = 0; i < n; i++) (*start)[key[i] + 1]++;
  for (int64_t b = 0; b < nb; b++) (*start)[b + 1] += (*start)[b];
  int64_t *pos = NULL;
  I2M_CALL(i2m_malloc((size_t)nb + 1, sizeof *pos, &pos));
  memcpy(pos, *start, ((size_t)nb + 1) * sizeof *pos);
  for (int64_t i = 0; i < n; i++) (*order)[pos[key[i]]++] = i;
  i2m_free(&pos);
  return I2M_OK;
}

/* The label whose region an interface pair's triangles' normals point out of.  The one place
 * that knows the orientation convention of i2m_tetmesh_t (tetmesh.h: the normal points from
 * tri_label[2i+1], the higher label, to tri_label[2i]). */
static int64_t pair_label_left_by_normal(const int64_t *pair) { return pair[1]; }

/* Each volume's bounding surfaces: the surface entity (pair p: tag p + 1) of every pair that
 * holds its label, + when the pair's normals point out of the volume, - when into it. */
static i2m_err_t gm_bounding_surfaces(gm_ent_t *e)
{
  I2M_CALL(i2m_calloc((size_t)e->nlab + 1, sizeof *e->bstart, &e->bstart));
  I2M_CALL(i2m_malloc((size_t)(2 * e->npair + 1), sizeof *e->bsurf, &e->bsurf));
  int64_t *fill = NULL;
  I2M_CALL(i2m_calloc((size_t)e->nlab + 1, sizeof *fill, &fill));
  for (int pass = 0; pass < 2; pass++) { /* count, then place */
    for (int64_t p = 0; p < e->npair; p++)
      for (int side = 0; side < 2; side++) {
        const int64_t v = e->pairs[2 * p + side], l = e->nlab ? find_label(e, v) : 0;
        if (e->nlab == 0 || e->lab[l] != v) continue; /* (the background: no volume) */
        if (pass == 0) {
          e->bstart[l + 1]++;
          continue;
        }
        const int32_t sign = v == pair_label_left_by_normal(e->pairs + 2 * p) ? 1 : -1;
        e->bsurf[e->bstart[l] + fill[l]++] = sign * (int32_t)(p + 1);
      }
    for (int64_t l = 0; pass == 0 && l < e->nlab; l++) e->bstart[l + 1] += e->bstart[l];
  }
  i2m_free(&fill);
  return I2M_OK;
}

/* A tissue name made fit for a quoted Gmsh name into out[GM_NAME_MAX + 1]: no quote (as ')
 * and no control character (as _), cut at a character boundary; "" when there is none. */
static void gm_sanitise(const char *name, char *out)
{
  size_t n = 0;
  for (; name && name[n] && n < GM_NAME_MAX; n++) {
    const unsigned char ch = (unsigned char)name[n];
    out[n] = ch == '"' ? '\'' : ch < 0x20 || ch == 0x7f ? '_' : (char)ch;
  }
  if (name && name[n]) /* (cut: not inside a UTF-8 sequence) */
    while (n > 0 && ((unsigned char)out[n] & 0xC0) == 0x80) n--;
  out[n] = '\0';
}

static int cmp_name(const void *a, const void *b) { return strcmp(**(char *const *const *)a, **(char *const *const *)b); }

/* The volumes' physical names: the tissue name of the label, else "label_<v>"; a tissue name
 * that two labels share gets "_<v>" after it (Gmsh and meshio key groups by name). */
static i2m_err_t gm_volume_names(gm_ent_t *e, const i2m_label_names_t *names)
{
  char buf[GM_NAME_MAX + 32];
  char ***order = NULL; /* [nlab] pointers to vol_name[l], sorted by name */
  I2M_CALL(i2m_calloc((size_t)e->nlab + 1, sizeof *e->vol_name, &e->vol_name));
  I2M_CALL(i2m_malloc((size_t)e->nlab + 1, sizeof *order, &order));
  i2m_err_t err = I2M_OK;
  for (int64_t l = 0; l < e->nlab && err == I2M_OK; l++) {
    gm_sanitise(i2m_label_name(names, e->lab[l]), buf);
    if (!buf[0]) snprintf(buf, sizeof buf, "label_%lld", (long long)e->lab[l]);
    err = i2m_malloc(strlen(buf) + 32, 1, &e->vol_name[l]);
    if (err == I2M_OK) strcpy(e->vol_name[l], buf);
    order[l] = &e->vol_name[l];
  }
  if (err == I2M_OK) qsort(order, (size_t)e->nlab, sizeof *order, cmp_name);
  int64_t run = 0; /* order[run .. i-1] share a name: each gets its value after it */
  for (int64_t i = 1; err == I2M_OK && i <= e->nlab; i++) {
    if (i < e->nlab && strcmp(*order[i], *order[run]) == 0) continue;
    for (int64_t k = run; i - run > 1 && k < i; k++) {
      const int64_t l = order[k] - e->vol_name; /* (order[k] points into vol_name) */
      snprintf(*order[k] + strlen(*order[k]), 32, "_%lld", (long long)e->lab[l]);
    }
    run = i;
  }
  i2m_free(&order);
  return err;
}

static i2m_err_t gm_entities(const i2m_tetmesh_t *m, const char *path, const i2m_label_names_t *names, gm_ent_t *e)
{
  int64_t *key = NULL;
  i2m_err_t err = I2M_OK;
  memset(e, 0, sizeof *e);
  /* distinct labels, kept sorted (few of them: insertion into a small array) */
  int64_t cap = 64, prev = 0;
  I2M_CALL(i2m_malloc((size_t)cap, sizeof *e->lab, &e->lab));
  for (int64_t t = 0; t < m->nt; t++) {
    int64_t v = m->tet_label[t];
    if (t > 0 && v == prev) continue;
    prev = v;
    int64_t k = e->nlab ? find_label(e, v) : 0;
    if (k < e->nlab && e->lab[k] == v) continue;
    if (k == e->nlab - 1 && e->lab[k] < v) k++;
    if (e->nlab == cap) {
      cap *= 2;
      I2M_CALL(i2m_realloc((size_t)cap, sizeof *e->lab, &e->lab));
    }
    memmove(e->lab + k + 1, e->lab + k, (size_t)(e->nlab - k) * sizeof *e->lab);
    e->lab[k] = v;
    e->nlab++;
  }
  for (int64_t l = 0; l < e->nlab; l++)
    I2M_CHECK(e->lab[l] > 0 && e->lab[l] <= INT32_MAX, I2M_ERR_UNSUPPORTED,
              "%s: Gmsh can't represent tetrahedron label %lld: physical tags must be positive "
              "32-bit integers (write .vtu or .mesh instead)",
              path, (long long)e->lab[l]);
  I2M_CALL(io_interface_pairs(m, &e->pairs, &e->npair, &e->tri_pair));
  int64_t maxlab = e->nlab ? e->lab[e->nlab - 1] : 0;
  I2M_CHECK(maxlab + 1 + e->npair < INT32_MAX, I2M_ERR_UNSUPPORTED,
            "%s: too many interface pairs for Gmsh physical tags", path);
  e->surf_tag0 = (int32_t)(maxlab + 1);
  int64_t nkey = m->nt > m->ntri ? m->nt : m->ntri;
  I2M_CALL(i2m_malloc((size_t)nkey, sizeof *key, &key));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)(e->nlab + e->npair) * 6, sizeof(double), &e->box));
  for (int64_t b = 0; b < e->nlab + e->npair; b++)
    for (int a = 0; a < 3; a++) {
      e->box[6 * b + a] = DBL_MAX;
      e->box[6 * b + 3 + a] = -DBL_MAX;
    }
  for (int64_t t = 0; t < m->nt; t++) {
    key[t] = find_label(e, m->tet_label[t]);
    for (int i = 0; i < 4; i++) box_add(e->box + 6 * key[t], m->xyz + 3 * m->tet[4 * t + i]);
  }
  I2M_CALL_GOTO(err, done, group(m->nt, e->nlab, key, &e->tstart, &e->torder));
  for (int64_t i = 0; i < m->ntri; i++) {
    key[i] = e->tri_pair[i];
    for (int j = 0; j < 3; j++)
      box_add(e->box + 6 * (e->nlab + key[i]), m->xyz + 3 * m->tri[3 * i + j]);
  }
  I2M_CALL_GOTO(err, done, group(m->ntri, e->npair, key, &e->fstart, &e->forder));
  I2M_CALL_GOTO(err, done, gm_bounding_surfaces(e));
  I2M_CALL_GOTO(err, done, gm_volume_names(e, names));
done:
  i2m_free(&key);
  return err;
}

static void gm_header(gm_t *g, const gm_ent_t *e)
{
  io_out_printf(&g->o, "$MeshFormat\n%s %d 8\n", g->v22 ? "2.2" : "4.1", g->ascii ? 0 : 1);
  if (!g->ascii) {
    gm_int(g, 1);
    io_out_put(&g->o, "\n", 1);
  }
  io_out_printf(&g->o, "$EndMeshFormat\n$PhysicalNames\n%lld\n", (long long)(e->nlab + e->npair));
  for (int64_t l = 0; l < e->nlab; l++)
    io_out_printf(&g->o, "3 %lld \"%s\"\n", (long long)e->lab[l], e->vol_name[l]);
  for (int64_t p = 0; p < e->npair; p++)
    io_out_printf(&g->o, "2 %lld \"interface_%lld_%lld\"\n", (long long)(e->surf_tag0 + p),
                  (long long)e->pairs[2 * p], (long long)e->pairs[2 * p + 1]);
  io_out_printf(&g->o, "$EndPhysicalNames\n");
}

/* MSH 4.1: the surfaces (no bounding curves), then the volumes with their surfaces. */
static void gm_entities_section(gm_t *g, const gm_ent_t *e)
{
  io_out_printf(&g->o, "$Entities\n");
  gm_size(g, 0);
  gm_size(g, 0);
  gm_size(g, (uint64_t)e->npair);
  gm_size(g, (uint64_t)e->nlab);
  gm_eol(g);
  for (int64_t b = 0; b < e->npair + e->nlab; b++) {
    int surf = b < e->npair;
    int64_t ent = surf ? b : b - e->npair;
    gm_int(g, (int32_t)(ent + 1));
    for (int a = 0; a < 6; a++) gm_dbl(g, e->box[6 * (surf ? e->nlab + ent : ent) + a]);
    gm_size(g, 1);
    gm_int(g, surf ? (int32_t)(e->surf_tag0 + ent) : (int32_t)e->lab[ent]);
    const int64_t first = surf ? 0 : e->bstart[ent], end = surf ? 0 : e->bstart[ent + 1];
    gm_size(g, (uint64_t)(end - first));
    for (int64_t k = first; k < end; k++) gm_int(g, e->bsurf[k]);
    gm_eol(g);
  }
  io_out_printf(&g->o, "%s$EndEntities\n", g->ascii ? "" : "\n");
}

static void gm_nodes(gm_t *g, const i2m_tetmesh_t *m)
{
  io_out_printf(&g->o, "$Nodes\n");
  gm_size(g, m->nv > 0 ? 1 : 0);
  gm_size(g, (uint64_t)m->nv);
  gm_size(g, m->nv > 0 ? 1 : 0);
  gm_size(g, (uint64_t)m->nv);
  gm_eol(g);
  if (m->nv > 0) {
    gm_int(g, 3);
    gm_int(g, 1);
    gm_int(g, 0);
    gm_size(g, (uint64_t)m->nv);
    gm_eol(g);
    for (int64_t v = 0; v < m->nv && g->o.err == I2M_OK; v++) {
      gm_size(g, (uint64_t)v + 1);
      gm_eol(g);
    }
    for (int64_t v = 0; v < m->nv && g->o.err == I2M_OK; v++) {
      for (int a = 0; a < 3; a++) gm_dbl(g, m->xyz[3 * v + a]);
      gm_eol(g);
    }
  }
  io_out_printf(&g->o, "%s$EndNodes\n", g->ascii ? "" : "\n");
}

/* MSH 2.2: the count as text, then per node its tag and coordinates (binary: int32, 3 doubles). */
static void gm_nodes_22(gm_t *g, const i2m_tetmesh_t *m)
{
  io_out_printf(&g->o, "$Nodes\n%lld\n", (long long)m->nv);
  for (int64_t v = 0; v < m->nv && g->o.err == I2M_OK; v++) {
    gm_int(g, (int32_t)(v + 1));
    for (int a = 0; a < 3; a++) gm_dbl(g, m->xyz[3 * v + a]);
    gm_eol(g);
  }
  io_out_printf(&g->o, "%s$EndNodes\n", g->ascii ? "" : "\n");
}

static void gm_block(gm_t *g, int dim, int64_t ent, int64_t n, const int64_t *order,
                     const int32_t *conn, int nper, uint64_t *tag)
{
  gm_int(g, dim);
  gm_int(g, (int32_t)(ent + 1));
  gm_int(g, dim == 3 ? 4 : 2);
  gm_size(g, (uint64_t)n);
  gm_eol(g);
  if (!g->ascii) { /* binary: straight into the buffer, 8 * (1 + nper) bytes per element */
    size_t eb = 8 * (size_t)(1 + nper);
    for (int64_t s = 0; s < n; s += 4096) {
      int64_t e = s + 4096 < n ? s + 4096 : n;
      char *p = io_out_reserve(&g->o, (size_t)(e - s) * eb);
      if (!p) return;
      for (int64_t i = s; i < e; i++, p += eb) {
        const int32_t *c = conn + (int64_t)nper * order[i];
        io_le64(p, ++*tag);
        for (int j = 0; j < nper; j++) io_le64(p + 8 * (j + 1), (uint64_t)c[j] + 1);
      }
      io_out_commit(&g->o, (size_t)(e - s) * eb);
    }
    return;
  }
  for (int64_t i = 0; i < n && g->o.err == I2M_OK; i++) {
    const int32_t *c = conn + (int64_t)nper * order[i];
    gm_size(g, ++*tag);
    for (int j = 0; j < nper; j++) gm_size(g, (uint64_t)c[j] + 1);
    gm_eol(g);
  }
}

/* MSH 2.2: the elements of one entity, each "tag type 2 physical elementary nodes..."
 * (binary: one header type, count, 2 tags, then int32 tag, the two tags, the nodes). */
static void gm_block_22(gm_t *g, int dim, int64_t ent, int32_t phys, int64_t n, const int64_t *order,
                        const int32_t *conn, int nper, uint64_t *tag)
{
  const int32_t type = dim == 3 ? 4 : 2;
  if (!g->ascii && n > 0) {
    gm_int(g, type);
    gm_int(g, (int32_t)n);
    gm_int(g, 2);
  }
  for (int64_t i = 0; i < n && g->o.err == I2M_OK; i++) {
    const int32_t *c = conn + (int64_t)nper * order[i];
    gm_int(g, (int32_t)++*tag);
    if (g->ascii) {
      gm_int(g, type);
      gm_int(g, 2);
    }
    gm_int(g, phys);
    gm_int(g, (int32_t)(ent + 1));
    for (int j = 0; j < nper; j++) gm_int(g, c[j] + 1);
    gm_eol(g);
  }
}

static void gm_elements(gm_t *g, const i2m_tetmesh_t *m, const gm_ent_t *e)
{
  uint64_t total = (uint64_t)(m->nt + m->ntri), tag = 0;
  io_out_printf(&g->o, "$Elements\n");
  if (g->v22) {
    io_out_printf(&g->o, "%llu\n", (unsigned long long)total);
  } else {
    gm_size(g, (uint64_t)(e->nlab + e->npair));
    gm_size(g, total);
    gm_size(g, total ? 1 : 0);
    gm_size(g, total);
    gm_eol(g);
  }
  for (int64_t l = 0; l < e->nlab; l++) {
    const int64_t n = e->tstart[l + 1] - e->tstart[l], *order = e->torder + e->tstart[l];
    if (g->v22) gm_block_22(g, 3, l, (int32_t)e->lab[l], n, order, m->tet, 4, &tag);
    else gm_block(g, 3, l, n, order, m->tet, 4, &tag);
  }
  for (int64_t p = 0; p < e->npair; p++) {
    const int64_t n = e->fstart[p + 1] - e->fstart[p], *order = e->forder + e->fstart[p];
    if (g->v22) gm_block_22(g, 2, p, (int32_t)(e->surf_tag0 + p), n, order, m->tri, 3, &tag);
    else gm_block(g, 2, p, n, order, m->tri, 3, &tag);
  }
  io_out_printf(&g->o, "%s$EndElements\n", g->ascii ? "" : "\n");
}

i2m_err_t io_write_gmsh(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts)
{
  I2M_CHECK(opts->msh_version == 41 || opts->msh_version == 22, I2M_ERR_ARG,
            "%s: MSH version %d.%d is not one i2m writes (4.1 or 2.2)", path, opts->msh_version / 10,
            opts->msh_version % 10);
  I2M_CHECK(opts->msh_version == 41 || (m->nv < INT32_MAX && m->nt + m->ntri < INT32_MAX), I2M_ERR_UNSUPPORTED,
            "%s: %lld nodes and %lld elements are more than MSH 2.2's 32-bit tags hold; write MSH 4.1", path,
            (long long)m->nv, (long long)(m->nt + m->ntri));
  gm_ent_t e;
  gm_t g;
  i2m_err_t err = gm_entities(m, path, opts->names, &e);
  if (err == I2M_OK) err = io_out_open(&g.o, path);
  if (err == I2M_OK) {
    g.ascii = opts->ascii;
    g.v22 = opts->msh_version == 22;
    gm_header(&g, &e);
    if (g.v22) {
      gm_nodes_22(&g, m);
    } else {
      gm_entities_section(&g, &e);
      gm_nodes(&g, m);
    }
    gm_elements(&g, m, &e);
    err = io_out_close(&g.o);
  }
  gm_ent_free(&e);
  return err;
}
