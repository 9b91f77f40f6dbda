/* Unit tests of pieces.c's fragment rule (pieces_group_is_fragment): a piece of a label is a
 * fragment when it is small in tets and in volume next to the image component it lies in.
 * The tets bound grows after a sliver pass (pieces_small_tets): the pass refines small pieces
 * too (on the knee at 6 M tets, a speck of half a voxel went from a fragment's 40-60 tets to
 * 68 and counted as a second piece of its tissue), while the volume bounds stay. */
#include <stdlib.h>

#include "../../src/refine/refine_impl.h"
#include "test_util.h"

enum { SIDE = 12 };

/* A cube of label 3 (SIDE^3 voxels of 0.5 x 0.5 x 1 mm) in a border of 0. */
static i2m_image_t *cube_image(void)
{
  int64_t n[3] = {SIDE + 4, SIDE + 4, SIDE + 4};
  int64_t *v = calloc((size_t)(n[0] * n[1] * n[2]), sizeof *v);
  for (int64_t k = 2; k < SIDE + 2; k++)
    for (int64_t j = 2; j < SIDE + 2; j++)
      for (int64_t i = 2; i < SIDE + 2; i++) v[(k * n[1] + j) * n[0] + i] = 3;
  const double sp[3] = {0.5, 0.5, 1.0}, origin[3] = {0, 0, 0};
  i2m_image_t *img = NULL;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, origin, NULL, v, &img) == I2M_OK);
  free(v);
  return img;
}

static void test_fragment_bounds(void)
{
  i2m_image_t *img = cube_image();
  i2m_edt_t *edt = NULL;
  i2m_refine_t *r = NULL;
  i2m_refine_params_t p;
  i2m_refine_params_default(&p);
  CU_ASSERT_FATAL(i2m_edt_create(img, &edt) == I2M_OK);
  CU_ASSERT_FATAL(i2m_refine_create(img, edt, &p, &r) == I2M_OK);
  CU_ASSERT_FATAL(i2m_edt_components(edt, &r->pieces_ic) == I2M_OK);
  const int64_t comp = i2m_components_find(&r->pieces_ic, 5, 5, 5);
  CU_ASSERT_FATAL(comp >= 0);
  CU_ASSERT_EQUAL_FATAL(r->pieces_ic.size[comp], SIDE * SIDE * SIDE);
  const double voxel = 0.25;
  i2m_group_t g = {.ntets = 40, .volume = 2.0 * voxel, .comp = comp, .relabel = -1, .label = 1};
  CU_ASSERT(pieces_group_is_fragment(r, &g));
  g.ntets = PIECE_SMALL_TETS + 4; /* as the pass may leave it */
  CU_ASSERT(!pieces_group_is_fragment(r, &g));
  r->sliver_pass_ran = true;
  CU_ASSERT(pieces_group_is_fragment(r, &g));
  g.ntets = PIECE_SMALL_TETS * PIECE_SLIVER_GROWTH + 1; /* a bound still */
  CU_ASSERT(!pieces_group_is_fragment(r, &g));
  g.ntets = 40;
  g.volume = PIECE_FRAGMENT_VOXELS * voxel; /* the volume bounds unchanged by the pass */
  CU_ASSERT(!pieces_group_is_fragment(r, &g));
  g.volume = 2.0 * voxel;
  g.comp = -1; /* in no component of the image */
  CU_ASSERT(!pieces_group_is_fragment(r, &g));
  i2m_refine_destroy(&r);
  i2m_edt_destroy(&edt);
  i2m_image_destroy(&img);
}

static const test_case_t cases[] = {
    {"fragment bounds before and after a sliver pass", test_fragment_bounds},
};

TEST_MAIN("refine pieces", cases)
