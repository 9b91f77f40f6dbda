/* libFuzzer harness: i2m-check's mesh readers (VTU, Medit, Gmsh 4.1 and 2.2, ASCII and binary:
 * the version comes from the content of a .msh; a .pvtu's own XML). */
#include "check.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
  static const char *const exts[] = {".vtu", ".mesh", ".msh", ".pvtu"};
  const char *path = fuzz_file(data, size, exts, sizeof exts / sizeof *exts);
  if (!path) return 0;
  ck_mesh_t m;
  memset(&m, 0, sizeof m);
  if (ck_mesh_read(path, &m) == I2M_OK) ck_mesh_free(&m);
  remove(path);
  return 0;
}
