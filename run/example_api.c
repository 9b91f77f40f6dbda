/* The library call of include/i2m.h in a few lines: a label image made in memory (a ball of
 * label 2 inside a ball of label 1, 1 mm voxels), meshed, and its per-label volumes printed
 * beside the voxels' (the mesh follows the tissue boundaries, so they agree within a few %).
 *
 *   cc run/example_api.c $(pkg-config --cflags --libs i2m) -o example_api && ./example_api [N]
 *
 * Prints "points P tets T triangles F" and one line per label: "label L tets N volume V voxels W". */
#include <i2m.h>
#include <stdio.h>
#include <stdlib.h>

/* |a b c d| / 6 of a tet's corners (positive for the library's orientation). */
static double tet_volume(const double *p, const int32_t *t)
{
  const double *a = p + 3 * t[0], *b = p + 3 * t[1], *c = p + 3 * t[2], *d = p + 3 * t[3];
  double u[3], v[3], w[3];
  for (int k = 0; k < 3; k++) {
    u[k] = b[k] - a[k];
    v[k] = c[k] - a[k];
    w[k] = d[k] - a[k];
  }
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0])) / 6;
}

int main(int argc, char **argv)
{
  const int n = argc > 1 ? atoi(argv[1]) : 40;
  if (n < 8 || n > 400) {
    fprintf(stderr, "example_api: N must be between 8 and 400\n");
    return 2;
  }
  uint8_t *labels = malloc((size_t)n * n * n);
  if (!labels) return 1;
  long voxels[3] = {0, 0, 0};
  for (int k = 0; k < n; k++) /* (i fastest) */
    for (int j = 0; j < n; j++)
      for (int i = 0; i < n; i++) {
        const double x = i - n / 2.0 + 0.5, y = j - n / 2.0 + 0.5, z = k - n / 2.0 + 0.5, r2 = x * x + y * y + z * z;
        const uint8_t l = r2 < 0.04 * n * n ? 2 : r2 < 0.16 * n * n ? 1 : 0;
        labels[((size_t)k * n + j) * n + i] = l;
        voxels[l]++;
      }
  const int64_t dims[3] = {n, n, n};
  const double spacing[3] = {1, 1, 1};
  i2m_options_t o;
  i2m_options_init(&o);
  o.deterministic = 1;
  i2m_mesh_t *m = NULL;
  if (i2m_mesh_labels(labels, I2M_LABELS_UINT8, dims, spacing, NULL, NULL, &o, &m) != 0) {
    fprintf(stderr, "example_api: %s\n", i2m_last_error());
    free(labels);
    return 1;
  }
  printf("points %lld tets %lld triangles %lld\n", (long long)m->npoints, (long long)m->ntets, (long long)m->ntriangles);
  for (int64_t l = 1; l <= 2; l++) {
    double volume = 0;
    long tets = 0;
    for (int64_t t = 0; t < m->ntets; t++)
      if (m->materials[t] == l) {
        volume += tet_volume(m->points, m->tets + 4 * t);
        tets++;
      }
    printf("label %lld tets %ld volume %.1f voxels %ld\n", (long long)l, tets, volume, voxels[l]);
  }
  i2m_mesh_free(&m);
  free(labels);
  return 0;
}
