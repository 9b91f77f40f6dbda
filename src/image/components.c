/* Image layer: 6-connected components of a block of labels.  Each row (j, k) is cut into runs
 * of one label along i; runs of neighbouring rows (j - 1, and k - 1) that overlap and share
 * a label are united (union-find over runs, by index).  Memory grows with the runs, not the
 * voxels. */
#include "i2m/image.h"

#include <string.h>

static int64_t uf_find(int64_t *par, int64_t x)
{
  while (par[x] != x) {
    par[x] = par[par[x]];
    x = par[x];
  }
  return x;
}

static void uf_union(int64_t *par, int64_t a, int64_t b)
{
  a = uf_find(par, a);
  b = uf_find(par, b);
  if (a != b) par[a < b ? b : a] = a < b ? a : b;
}

/* Unites the runs of rows a and b (each sorted by x0) that overlap and share a label. */
static void join_rows(i2m_components_t *c, int64_t a, int64_t b)
{
  int64_t i = c->row[a], j = c->row[b];
  while (i < c->row[a + 1] && j < c->row[b + 1]) {
    const int64_t ie = c->x0[i] + c->len[i], je = c->x0[j] + c->len[j];
    if (c->x0[i] < je && c->x0[j] < ie && c->lab[i] == c->lab[j]) uf_union(c->par, i, j);
    if (ie < je)
      i++;
    else
      j++;
  }
}

static i2m_err_t runs_room(i2m_components_t *c, int64_t need, int64_t *cap)
{
  if (need <= *cap) return I2M_OK;
  const int64_t n = need + need / 2 + 1024;
  I2M_CALL(i2m_realloc((size_t)n, sizeof *c->x0, &c->x0));
  I2M_CALL(i2m_realloc((size_t)n, sizeof *c->len, &c->len));
  I2M_CALL(i2m_realloc((size_t)n, sizeof *c->lab, &c->lab));
  I2M_CALL(i2m_realloc((size_t)n, sizeof *c->par, &c->par));
  *cap = n;
  return I2M_OK;
}

/* Cuts every row into runs (one row of labels at a time, read into buf). */
static i2m_err_t cut_runs(i2m_components_t *c, i2m_label_row_fn read_row, const void *ctx, uint16_t *buf)
{
  int64_t cnt = 0, cap = 0;
  for (int64_t k = 0; k < c->n[2]; k++)
    for (int64_t j = 0; j < c->n[1]; j++) {
      c->row[k * c->n[1] + j] = cnt;
      read_row(ctx, c->lo[0], c->lo[1] + j, c->lo[2] + k, c->n[0], buf);
      for (int64_t i = 0; i < c->n[0]; i++) {
        if (i > 0 && buf[i] == buf[i - 1]) {
          c->len[cnt - 1]++;
          continue;
        }
        I2M_CALL(runs_room(c, cnt + 1, &cap));
        c->x0[cnt] = (int32_t)i;
        c->len[cnt] = 1;
        c->lab[cnt] = buf[i];
        c->par[cnt] = cnt;
        cnt++;
      }
    }
  c->nruns = cnt;
  return I2M_OK;
}

i2m_err_t i2m_components_build(const int64_t lo[3], const int64_t n[3], i2m_label_row_fn read_row, const void *ctx,
                               i2m_components_t *c)
{
  memset(c, 0, sizeof *c);
  for (int a = 0; a < 3; a++) {
    c->lo[a] = lo[a];
    c->n[a] = n[a];
  }
  const int64_t nrows = n[1] * n[2];
  uint16_t *buf = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, fail, i2m_malloc((size_t)n[0], sizeof *buf, &buf));
  I2M_CALL_GOTO(err, fail, i2m_malloc((size_t)nrows + 1, sizeof *c->row, &c->row));
  I2M_CALL_GOTO(err, fail, cut_runs(c, read_row, ctx, buf));
  c->row[nrows] = c->nruns;
  I2M_CALL_GOTO(err, fail, i2m_calloc((size_t)c->nruns, sizeof *c->size, &c->size));
  for (int64_t k = 0; k < n[2]; k++)
    for (int64_t j = 0; j < n[1]; j++) {
      const int64_t row = k * n[1] + j;
      if (j > 0) join_rows(c, row, row - 1);
      if (k > 0) join_rows(c, row, row - n[1]);
    }
  for (int64_t i = 0; i < c->nruns; i++) {
    c->par[i] = uf_find(c->par, i);
    c->size[c->par[i]] += c->len[i];
  }
  i2m_free(&buf);
  return I2M_OK;
fail:
  i2m_free(&buf);
  i2m_components_free(c);
  return err;
}

/* The run that holds voxel (i,j,k), -1 outside the block. */
static int64_t run_of(const i2m_components_t *c, int64_t i, int64_t j, int64_t k)
{
  i -= c->lo[0];
  j -= c->lo[1];
  k -= c->lo[2];
  if (i < 0 || j < 0 || k < 0 || i >= c->n[0] || j >= c->n[1] || k >= c->n[2]) return -1;
  int64_t row = k * c->n[1] + j, lo = c->row[row], hi = c->row[row + 1] - 1;
  while (lo < hi) { /* the last run starting at or before i */
    const int64_t mid = (lo + hi + 1) / 2;
    if (c->x0[mid] <= i)
      lo = mid;
    else
      hi = mid - 1;
  }
  return lo;
}

int64_t i2m_components_find(const i2m_components_t *c, int64_t i, int64_t j, int64_t k)
{
  const int64_t run = run_of(c, i, j, k);
  return run < 0 ? -1 : c->par[run];
}

int64_t i2m_components_find_label(const i2m_components_t *c, int64_t i, int64_t j, int64_t k, int lab)
{
  const int64_t run = run_of(c, i, j, k);
  return run < 0 || c->lab[run] != lab ? -1 : c->par[run];
}

void i2m_components_free(i2m_components_t *c)
{
  i2m_free(&c->row);
  i2m_free(&c->x0);
  i2m_free(&c->len);
  i2m_free(&c->lab);
  i2m_free(&c->par);
  i2m_free(&c->size);
  c->nruns = 0;
}

static void image_row(const void *ctx, int64_t i0, int64_t j, int64_t k, int64_t n, uint16_t *out)
{
  const i2m_image_t *img = ctx;
  const int64_t v = (k * img->n[1] + j) * img->n[0] + i0;
  for (int64_t i = 0; i < n; i++) out[i] = (uint16_t)i2m_image_index(img, v + i);
}

i2m_err_t i2m_image_components(const i2m_image_t *img, i2m_components_t *c)
{
  const int64_t lo[3] = {0, 0, 0};
  return i2m_components_build(lo, img->n, image_row, img, c);
}
