/* io layer: Medit ASCII writer (.mesh).  Vertices (ref 0), tetrahedra (ref = label value),
 * interface triangles (ref = number of the label pair, 1..P in (a,b) order).  A comment
 * block before "Triangles" maps each number to its pair:
 *   # i2m interface 3 = labels 13 20
 * Vertex ids are 1-based; coordinates are printed with %.17g (exact round trip).
 * Tools such as mmg drop comments, so the same map also goes to a JSON side file beside the
 * mesh, "<name>.mesh.json" (the mesh's whole name plus .json: never the name of a run report
 * "<name>.json" next to it):
 *   {"mesh": "<name>.mesh", "tetrahedra": {"ref": "label value", "labels": [...]},
 *    "triangles": {"ref": "interface", "orientation": "..."},
 *    "interfaces": [{"ref": 1, "labels": [0, 84]}, ...]}
 * with "names" beside "labels" when the image names its tissues.  Both files are written
 * under temporary names and renamed into place together at the end. */
#include "io_impl.h"

#include <stdio.h>
#include <string.h>

#define MEDIT_LINE 512

static void medit_vertices(io_out_t *o, const i2m_tetmesh_t *m)
{
  io_out_printf(o, "Vertices\n%lld\n", (long long)m->nv);
  for (int64_t v = 0; v < m->nv; v++) {
    char *p = io_out_reserve(o, MEDIT_LINE);
    if (!p) return;
    const double *x = m->xyz + 3 * v;
    int k = snprintf(p, MEDIT_LINE, "%.17g %.17g %.17g 0\n", x[0], x[1], x[2]);
    io_out_commit(o, (size_t)k);
  }
}

/* One element line: n 1-based ids then the ref. */
static void medit_element(io_out_t *o, const int32_t *ids, int n, int64_t ref)
{
  char *p = io_out_reserve(o, MEDIT_LINE);
  if (!p) return;
  int k = 0;
  for (int i = 0; i < n; i++) {
    k += io_fmt_i64(p + k, (int64_t)ids[i] + 1);
    p[k++] = ' ';
  }
  k += io_fmt_i64(p + k, ref);
  p[k++] = '\n';
  io_out_commit(o, (size_t)k);
}

bool i2m_mesh_side_path(const char *path, char *out, size_t cap)
{
  if (i2m_format_from_path(path) != I2M_FORMAT_MEDIT) return false;
  int n = snprintf(out, cap, "%s.json", path);
  return n > 0 && (size_t)n < cap;
}

/* "names": [...] for a list of label values, when the image names any of them. */
static void side_names(FILE *f, const int64_t *values, int64_t n, const i2m_label_names_t *names)
{
  bool any = false;
  for (int64_t i = 0; i < n; i++) any = any || i2m_label_name(names, values[i]);
  if (!any) return;
  fprintf(f, ", \"names\": [");
  for (int64_t i = 0; i < n; i++) {
    const char *s = i2m_label_name(names, values[i]);
    if (i) fprintf(f, ", ");
    if (s)
      i2m_json_string(f, s);
    else
      fprintf(f, "null");
  }
  fprintf(f, "]");
}

/* The distinct tet labels of m, sorted (owned by the caller): a binary search per run of
 * equal labels in a sorted array that grows (at most I2M_MAX_LABELS of them). */
static i2m_err_t tet_labels(const i2m_tetmesh_t *m, int64_t **labels, int64_t *n)
{
  int64_t cap = 16, *l = NULL;
  *n = 0;
  I2M_CALL(i2m_malloc((size_t)cap, sizeof *l, &l));
  for (int64_t t = 0; t < m->nt; t++) {
    const int64_t v = m->tet_label[t];
    if (t > 0 && v == m->tet_label[t - 1]) continue;
    int64_t lo = 0, hi = *n;
    while (lo < hi) {
      const int64_t mid = (lo + hi) / 2;
      if (l[mid] < v) lo = mid + 1;
      else hi = mid;
    }
    if (lo < *n && l[lo] == v) continue;
    if (*n == cap) {
      cap *= 2;
      i2m_err_t err = i2m_realloc((size_t)cap, sizeof *l, &l);
      if (err != I2M_OK) {
        i2m_free(&l);
        return err;
      }
    }
    memmove(l + lo + 1, l + lo, (size_t)(*n - lo) * sizeof *l);
    l[lo] = v;
    (*n)++;
  }
  *labels = l;
  return I2M_OK;
}

/* The side file's JSON (see the top of this file). */
static i2m_err_t medit_side_json(FILE *f, const char *path, const i2m_tetmesh_t *m, const int64_t *pairs,
                                 int64_t npairs, const i2m_label_names_t *names)
{
  int64_t *labels = NULL, nl = 0;
  I2M_CALL(tet_labels(m, &labels, &nl));
  const char *slash = strrchr(path, '/');
  fprintf(f, "{\n  \"mesh\": ");
  i2m_json_string(f, slash ? slash + 1 : path);
  fprintf(f, ",\n  \"tetrahedra\": {\"ref\": \"label value\", \"labels\": [");
  for (int64_t i = 0; i < nl; i++) fprintf(f, "%s%lld", i ? ", " : "", (long long)labels[i]);
  fprintf(f, "]");
  side_names(f, labels, nl, names);
  fprintf(f, "},\n  \"triangles\": {\"ref\": \"interface\", \"orientation\": \"the normal (right-hand rule) "
             "points from labels[1] to labels[0], from the higher label to the lower: out of the domain where "
             "labels[0] is 0\"},\n  \"interfaces\": [");
  for (int64_t p = 0; p < npairs; p++) {
    fprintf(f, "%s\n    {\"ref\": %lld, \"labels\": [%lld, %lld]", p ? "," : "", (long long)(p + 1),
            (long long)pairs[2 * p], (long long)pairs[2 * p + 1]);
    side_names(f, pairs + 2 * p, 2, names);
    fprintf(f, "}");
  }
  fprintf(f, "%s]\n}\n", npairs ? "\n  " : "");
  i2m_free(&labels);
  return I2M_OK;
}

i2m_err_t io_write_medit(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts)
{
  int64_t *pairs = NULL, npairs = 0;
  int32_t *tri_pair = NULL;
  char side_path[4096];
  i2m_outfile_t side = {0};
  io_out_t o;
  I2M_CHECK(i2m_mesh_side_path(path, side_path, sizeof side_path), I2M_ERR_ARG, "%s: file name too long", path);
  I2M_CALL(io_interface_pairs(m, &pairs, &npairs, &tri_pair));
  i2m_err_t err = i2m_outfile_open(&side, side_path, "w");
  if (err == I2M_OK) err = medit_side_json(side.f, path, m, pairs, npairs, opts->names);
  if (err == I2M_OK) err = io_out_open(&o, path);
  if (err != I2M_OK) goto done;
  io_out_printf(&o, "MeshVersionFormatted 2\n\nDimension 3\n\n");
  medit_vertices(&o, m);
  io_out_printf(&o, "\nTetrahedra\n%lld\n", (long long)m->nt);
  for (int64_t t = 0; t < m->nt; t++) medit_element(&o, m->tet + 4 * t, 4, m->tet_label[t]);
  if (m->ntri > 0) {
    io_out_printf(&o, "\n# i2m interfaces: a triangle's ref numbers the label pair (a,b)\n"
                      "# of the tissues on its two sides (0: outside); its normal points from\n"
                      "# b to a, from the higher label to the lower (out of the domain for 0).\n"
                      "# The same map is in the JSON side file <this file's name>.json.\n");
    for (int64_t p = 0; p < npairs; p++)
      io_out_printf(&o, "# i2m interface %lld = labels %lld %lld\n", (long long)(p + 1),
                    (long long)pairs[2 * p], (long long)pairs[2 * p + 1]);
    io_out_printf(&o, "Triangles\n%lld\n", (long long)m->ntri);
    for (int64_t i = 0; i < m->ntri; i++)
      medit_element(&o, m->tri + 3 * i, 3, (int64_t)tri_pair[i] + 1);
  }
  io_out_printf(&o, "\nEnd\n");
  err = io_out_close(&o); /* the mesh, then its side file: both or (nearly always) neither */
  if (err == I2M_OK) err = i2m_outfile_commit(&side);
done:
  if (side.f) i2m_outfile_abandon(&side);
  i2m_free(&pairs);
  i2m_free(&tri_pair);
  return err;
}
