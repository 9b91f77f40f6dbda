/* Unit tests of the submeshes the dist layer moves between ranks (layer 4, no MPI): two
 * refinement objects of one image stand for two ranks.  A refined mesh held by the first is
 * cut into the octree's tiles; tiles are packed, dropped and unpacked into the second and
 * back, in various orders.  At every step each side is a valid triangulation (its faces to
 * tiles it does not hold marked as another rank's), the two checksums add up to the original
 * one (every tet in exactly one place), and a submesh packed again after a round trip is the
 * same bytes. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/refine.h"
#include "test_util.h"

#define N 22

static int64_t nested(double x, double y, double z)
{
  double r = sqrt(x * x + y * y + z * z);
  return r < 4.5 ? 20 : r < 8.5 ? 7 : 0;
}

static i2m_image_t *make_image(void)
{
  int64_t n[3] = {N, N, N};
  const double sp[3] = {1.0, 0.8, 1.2};
  int64_t *v = malloc(sizeof(int64_t) * N * N * N);
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++)
        v[(k * N + j) * N + i] = nested((i - N / 2 + 0.5) * sp[0], (j - N / 2 + 0.5) * sp[1], (k - N / 2 + 0.5) * sp[2]);
  i2m_image_t *img = NULL;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, NULL, NULL, v, &img) == I2M_OK);
  free(v);
  return img;
}

typedef struct {
  i2m_image_t *img;
  i2m_edt_t *edt;
  i2m_refine_t *a, *b; /* two "ranks" */
  uint64_t sum;        /* the whole triangulation's checksum */
  int64_t ntets;
} two_t;

static void setup(two_t *T, int depth)
{
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  T->img = make_image();
  CU_ASSERT_FATAL(i2m_edt_create(T->img, &T->edt) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_create(T->img, T->edt, &p, &T->a) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_create(T->img, T->edt, &p, &T->b) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_run(T->a) == I2M_OK);
  T->sum = i2m_dt_checksum(i2m_refine_dt(T->a), &T->ntets);
  i2m_refine_set_depth(T->a, depth);
  i2m_refine_set_depth(T->b, depth);
  CU_ASSERT_FATAL(i2m_refine_octree_begin(T->a) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_octree_begin(T->b) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_dist_begin(T->a, true) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_dist_begin(T->b, false) == I2M_OK);
}

static void teardown(two_t *T)
{
  i2m_refine_destroy(&T->a);
  i2m_refine_destroy(&T->b);
  i2m_edt_destroy(&T->edt);
  i2m_image_destroy(&T->img);
}

/* Both sides valid (Delaunay where both sides of a face are held), every tet in one place. */
static void check_split(const two_t *T)
{
  int64_t na = 0, nb = 0;
  for (int side = 0; side < 2; side++) {
    i2m_err_t err = i2m_dt_check(i2m_refine_dt(side ? T->b : T->a), true);
    if (err) fprintf(stderr, "%s\n", i2m_error_message());
    CU_ASSERT_EQUAL(err, I2M_OK);
  }
  const uint64_t sa = i2m_dt_checksum(i2m_refine_dt(T->a), &na), sb = i2m_dt_checksum(i2m_refine_dt(T->b), &nb);
  CU_ASSERT_EQUAL(na + nb, T->ntets);
  CU_ASSERT(sa + sb == T->sum);
}

/* Tile id from one side to the other; returns the bytes sent. */
static size_t move(i2m_refine_t *from, i2m_refine_t *to, uint32_t id)
{
  void *buf = NULL;
  size_t len = 0;
  uint32_t got = 0;
  CU_ASSERT_FATAL(i2m_refine_pack(from, id, &buf, &len) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_drop(from, &id, 1) == I2M_OK);
  i2m_err_t err = i2m_refine_unpack(to, buf, len, &got);
  if (err) fprintf(stderr, "%s\n", i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  CU_ASSERT_EQUAL(got, id);
  CU_ASSERT(!i2m_refine_holds(from, id) && i2m_refine_holds(to, id));
  free(buf);
  return len;
}

static void test_round_trip_bytes(void)
{
  two_t T;
  setup(&T, 2);
  uint32_t ntiles = 64;
  for (uint32_t id = 0; id < ntiles; id += 5) {
    void *b1 = NULL, *b2 = NULL;
    size_t l1 = 0, l2 = 0;
    CU_ASSERT_FATAL(i2m_refine_pack(T.a, id, &b1, &l1) == I2M_OK);
    move(T.a, T.b, id);
    check_split(&T);
    CU_ASSERT_FATAL(i2m_refine_pack(T.b, id, &b2, &l2) == I2M_OK);
    CU_ASSERT_EQUAL(l1, l2);
    CU_ASSERT(l1 == l2 && memcmp(b1, b2, l1) == 0);
    free(b1);
    free(b2);
  }
  teardown(&T);
}

static void test_half_and_back(void)
{
  two_t T;
  setup(&T, 2);
  size_t bytes = 0;
  for (uint32_t id = 0; id < 64; id++) /* every other tile, in a checkerboard */
    if (((id & 3) + (id >> 2 & 3) + (id >> 4)) % 2) bytes += move(T.a, T.b, id);
  check_split(&T);
  CU_ASSERT(bytes > 0);
  for (uint32_t k = 0; k < 64; k++) { /* back, in another order */
    const uint32_t id = (k * 37 + 11) % 64;
    if (i2m_refine_holds(T.b, id)) move(T.b, T.a, id);
    if (k % 16 == 0) check_split(&T);
  }
  check_split(&T);
  int64_t nb = 0;
  i2m_dt_checksum(i2m_refine_dt(T.b), &nb);
  CU_ASSERT_EQUAL(nb, 0);
  uint32_t nv = i2m_dt_nverts_slots(i2m_refine_dt(T.b)), live = 0;
  for (uint32_t v = 8; v < nv; v++) live += i2m_refine_dt(T.b)->vkind[v] != I2M_VK_DEAD;
  CU_ASSERT_EQUAL(live, 0); /* every vertex left with the last tet that used it */
  teardown(&T);
}

static void test_all_over(void)
{
  two_t T;
  setup(&T, 1);
  for (uint32_t id = 0; id < 8; id++) move(T.a, T.b, id);
  check_split(&T);
  int64_t na = 0;
  i2m_dt_checksum(i2m_refine_dt(T.a), &na);
  CU_ASSERT_EQUAL(na, 0);
  for (uint32_t id = 8; id-- > 0;) move(T.b, T.a, id);
  check_split(&T);
  teardown(&T);
}

static const test_case_t tests[] = {
    {"pack, drop, unpack: the same bytes packed again", test_round_trip_bytes},
    {"half the tiles over and back, in another order", test_half_and_back},
    {"every tile over and back", test_all_over},
};
TEST_MAIN("submeshes between two ranks", tests)
