/* Unit tests of the Gmsh writer (layer 7) beyond the round trips of test_io_writers.c: MSH 4.1
 * and 2.2, ASCII and binary, read back by i2m-check's reader (tools/check, compiled in);
 * physical names from tissue names (sanitised, made unique); every volume entity's bounding
 * surfaces with their signs; an unknown version refused.  The mesh: two unit cubes side by
 * side (labels 5 and 7), six Kuhn tetrahedra each, with their interface triangles. */
#include "test_util.h"

#include "i2m/io.h"

#include "../../tools/check/ck_geom.c"
#include "../../tools/check/fidelity.c"
#include "../../tools/check/progress.c"
#include "../../tools/check/pvtu.c"
#include "../../tools/check/quality.c"
#include "../../tools/check/read_mesh.c"
#include "../../tools/check/validity.c"

#include <string.h>
#include <unistd.h>

static char tmp_dir[256];
static char tmp_buf[512];

static const char *tmp_path(const char *name)
{
  if (!tmp_dir[0]) {
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/i2m_test_gmsh_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
      perror("mkdtemp");
      abort();
    }
  }
  snprintf(tmp_buf, sizeof tmp_buf, "%s/%s", tmp_dir, name);
  return tmp_buf;
}

static double signed_volume(const double *x, const int32_t *t)
{
  const double *a = x + 3 * t[0], *b = x + 3 * t[1], *c = x + 3 * t[2], *d = x + 3 * t[3];
  double u[3], v[3], w[3];
  for (int k = 0; k < 3; k++) u[k] = b[k] - a[k], v[k] = c[k] - a[k], w[k] = d[k] - a[k];
  return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0]);
}

/* Face f of tet t, oriented with its normal out of the tet (positive tets). */
static void tet_face(const int32_t *t, int f, int32_t out[3])
{
  static const int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (int k = 0; k < 3; k++) out[k] = t[faces[f][k]];
}

static int same_face(const int32_t *a, const int32_t *b)
{
  int hits = 0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) hits += a[i] == b[j];
  return hits == 3;
}

/* The label of the tet across face f of tet t (0 outside). */
static int64_t label_across(const i2m_tetmesh_t *m, int64_t t, const int32_t *face)
{
  for (int64_t u = 0; u < m->nt; u++)
    for (int g = 0; u != t && g < 4; g++) {
      int32_t other[3];
      tet_face(m->tet + 4 * u, g, other);
      if (same_face(face, other)) return m->tet_label[u];
    }
  return 0;
}

/* Interface triangles as tetmesh.h says: labels (a < b, the background 0 first), the normal
 * from the higher label b to the lower a (out of the domain on the outer boundary). */
static void derive_triangles(i2m_tetmesh_t *m)
{
  m->ntri = 0;
  for (int64_t t = 0; t < m->nt; t++)
    for (int f = 0; f < 4; f++) {
      int32_t face[3];
      tet_face(m->tet + 4 * t, f, face);
      const int64_t mine = m->tet_label[t], other = label_across(m, t, face);
      if (other == mine || (other != 0 && other < mine)) continue; /* (each interface once) */
      int32_t *tri = m->tri + 3 * m->ntri;
      const int outward = mine > other; /* normal out of this tet: from mine, the higher, to other */
      tri[0] = face[0];
      tri[1] = outward ? face[1] : face[2];
      tri[2] = outward ? face[2] : face[1];
      m->tri_label[2 * m->ntri] = mine < other ? mine : other;
      m->tri_label[2 * m->ntri + 1] = mine < other ? other : mine;
      m->ntri++;
    }
}

static i2m_tetmesh_t *two_cubes(void)
{
  i2m_tetmesh_t *m = NULL;
  CU_ASSERT_FATAL(i2m_tetmesh_create(12, 12, 48, &m) == I2M_OK);
  for (int v = 0; v < 12; v++) { /* vertex (i, j, k), i = 0..2 */
    m->xyz[3 * v] = v % 3;
    m->xyz[3 * v + 1] = v / 3 % 2;
    m->xyz[3 * v + 2] = v / 6;
  }
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  const int step[3] = {1, 3, 6};
  for (int cube = 0; cube < 2; cube++)
    for (int p = 0; p < 6; p++) {
      int32_t *t = m->tet + 4 * (6 * cube + p);
      t[0] = cube;
      for (int k = 0; k < 3; k++) t[k + 1] = t[k] + step[perms[p][k]];
      if (signed_volume(m->xyz, t) < 0) {
        int32_t s = t[2];
        t[2] = t[3];
        t[3] = s;
      }
      m->tet_label[6 * cube + p] = cube ? 7 : 5;
    }
  derive_triangles(m);
  return m;
}

static char file_buf[1 << 16];
static size_t file_len;

/* The file's bytes (file_buf, file_len), NUL-terminated. */
static char *slurp(const char *path)
{
  FILE *f = fopen(path, "rb");
  CU_ASSERT_FATAL(f != NULL);
  file_len = fread(file_buf, 1, sizeof file_buf - 1, f);
  file_buf[file_len] = '\0';
  fclose(f);
  return file_buf;
}

/* Does the file read by slurp() hold @p s (binary files too)? */
static bool file_has(const char *s)
{
  const size_t n = strlen(s);
  for (size_t i = 0; i + n <= file_len; i++)
    if (memcmp(file_buf + i, s, n) == 0) return true;
  return false;
}

/* Writes with the options, reads back with i2m-check's reader, checks counts and validity. */
static void write_read(const i2m_tetmesh_t *m, const char *name, const i2m_write_opts_t *o)
{
  const char *path = tmp_path(name);
  i2m_err_t err = i2m_mesh_write(m, path, o);
  if (err) printf("\n  %s: %s\n", name, i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  ck_mesh_t r;
  err = ck_mesh_read(path, &r);
  if (err) printf("\n  %s: %s\n", name, i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  CU_ASSERT(r.nv == m->nv && r.nt == m->nt && r.ntri == m->ntri);
  CU_ASSERT(memcmp(r.xyz, m->xyz, (size_t)m->nv * 3 * sizeof(double)) == 0);
  CU_ASSERT(r.tri_labels_known);
  int64_t label_sum = 0, want = 0;
  for (int64_t t = 0; t < m->nt; t++) label_sum += r.tet_label[t], want += m->tet_label[t];
  CU_ASSERT(label_sum == want);
  ck_validity_t v;
  ck_topo_t topo;
  CU_ASSERT_FATAL(ck_validity(&r, &v, &topo) == I2M_OK);
  if (!v.valid) printf("\n  %s: %s\n", name, v.errors);
  CU_ASSERT(v.valid); /* (its triangles equal those derived from the tets, orientation too) */
  ck_topo_free(&topo);
  ck_mesh_free(&r);
}

static void test_versions(void)
{
  i2m_tetmesh_t *m = two_cubes();
  CU_ASSERT(m->ntri == 2 * 5 * 2 + 2); /* 10 outer squares, the shared one */
  static const struct {
    const char *name;
    int version;
    bool ascii;
    const char *head;
  } cases[] = {{"b41.msh", 41, false, "$MeshFormat\n4.1 1 8\n"}, {"a41.msh", 41, true, "$MeshFormat\n4.1 0 8\n"},
               {"b22.msh", 22, false, "$MeshFormat\n2.2 1 8\n"}, {"a22.msh", 22, true, "$MeshFormat\n2.2 0 8\n"}};
  for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
    i2m_write_opts_t o = i2m_write_opts_default();
    o.msh_version = cases[c].version;
    o.ascii = cases[c].ascii;
    write_read(m, cases[c].name, &o);
    const char *text = slurp(tmp_path(cases[c].name));
    CU_ASSERT(strncmp(text, cases[c].head, strlen(cases[c].head)) == 0);
    CU_ASSERT(file_has("$Entities") == (cases[c].version == 41));
    CU_ASSERT(file_has("3 5 \"label_5\"\n") && file_has("2 10 \"interface_5_7\"\n"));
    remove(tmp_path(cases[c].name));
  }
  i2m_tetmesh_destroy(&m);
}

static void test_names_and_boundaries(void)
{
  i2m_tetmesh_t *m = two_cubes();
  int64_t values[2] = {5, 7};
  char n5[] = "bone \"x\"\n", n7[] = "bone \"x\"\n", *nm[2] = {n5, n7};
  i2m_label_names_t names = {2, values, nm, NULL};
  i2m_write_opts_t o = i2m_write_opts_default();
  o.names = &names;
  o.ascii = true;
  write_read(m, "names.msh", &o);
  const char *text = slurp(tmp_path("names.msh"));
  /* no quote nor newline inside a name; a name two labels share made unique */
  CU_ASSERT(strstr(text, "3 5 \"bone 'x'__5\"\n") != NULL);
  CU_ASSERT(strstr(text, "3 7 \"bone 'x'__7\"\n") != NULL);
  /* surfaces 1 = (0,5), 2 = (0,7), 3 = (5,7); normals from b to a: out of 5 through 1, into 5
   * through 3, out of 7 through 2 and 3 */
  CU_ASSERT(strstr(text, " 1 5 2 1 -3 \n") != NULL);
  CU_ASSERT(strstr(text, " 1 7 2 2 3 \n") != NULL);
  remove(tmp_path("names.msh"));
  names.n = 1; /* label 7 without a name */
  write_read(m, "names.msh", &o);
  text = slurp(tmp_path("names.msh"));
  CU_ASSERT(strstr(text, "3 5 \"bone 'x'_\"\n") != NULL && strstr(text, "3 7 \"label_7\"\n") != NULL);
  remove(tmp_path("names.msh"));
  i2m_tetmesh_destroy(&m);
}

static void test_bad_version(void)
{
  i2m_tetmesh_t *m = two_cubes();
  i2m_write_opts_t o = i2m_write_opts_default();
  o.msh_version = 30;
  CU_ASSERT(i2m_mesh_write(m, tmp_path("v3.msh"), &o) == I2M_ERR_ARG);
  CU_ASSERT(access(tmp_path("v3.msh"), F_OK) != 0);
  i2m_tetmesh_destroy(&m);
}

static void test_cleanup(void)
{
  CU_ASSERT(rmdir(tmp_dir) == 0); /* every test removed its files */
}

static const test_case_t cases[] = {
    {"MSH 4.1 and 2.2, binary and ASCII, read back and valid", test_versions},
    {"physical names from tissue names; bounding surfaces with signs", test_names_and_boundaries},
    {"an unknown MSH version is refused", test_bad_version},
    {"scratch directory left empty", test_cleanup},
};

TEST_MAIN("io_gmsh", cases)
