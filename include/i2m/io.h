/* i2m io layer (layer 7): mesh writers.  The format follows the output file's extension:
 *   .vtu   VTK XML unstructured grid, binary appended data, cell data "material"
 *   .mesh  Medit ASCII: vertices, tetrahedra (ref = label value), interface triangles
 *          (ref = interface number; a comment block maps numbers to label pairs, and so does
 *          the JSON side file NAME.mesh.json written with it, which survives tools such as
 *          mmg that drop comments)
 *   .msh   Gmsh 4.1 (binary; ASCII with i2m_write_opts_t.ascii or the environment variable
 *          I2M_MSH_ASCII=1): one physical volume per label ("label_<v>", tag v > 0), one
 *          physical surface per interface pair ("interface_<a>_<b>", tags after the largest
 *          label).
 * Interface triangles (Medit, Gmsh) follow i2m_tetmesh_t: the label pair (a, b) has the lower
 * label first (the background 0, then tissues by value) and the normal (right-hand rule)
 * points from b to a, from the higher label to the lower: out of the meshed domain on the
 * outer boundary, as Medit, mmg and Gmsh expect of a boundary surface.
 * Output is buffered (large fwrite chunks) and every write is checked; a failed write
 * removes the partial file.  bin/i2m-check reads all three back (tools/check). */
#ifndef I2M_IO_H
#define I2M_IO_H

#include "i2m/dist.h"
#include "i2m/tetmesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Mesh file formats. */
typedef enum { I2M_FORMAT_UNKNOWN = 0, I2M_FORMAT_VTU, I2M_FORMAT_MEDIT, I2M_FORMAT_GMSH, I2M_FORMAT_PVTU } i2m_format_t;

/** How the writers write (i2m_write_opts_default() gives the defaults; NULL means them). */
typedef struct i2m_write_opts {
  const i2m_label_names_t *names; /**< borrowed, or NULL: tissue names for the formats that
                                       carry names (Gmsh physical names) */
  int msh_version;                /**< Gmsh: 41 (4.1, the default) or 22 (2.2) */
  bool ascii;                     /**< Gmsh: text instead of binary */
  bool compress;                  /**< VTU: zlib-compressed appended data (default true) */
} i2m_write_opts_t;

/** The default write options. */
i2m_write_opts_t i2m_write_opts_default(void);

/** Format for a file name (by extension, case-insensitive); I2M_FORMAT_UNKNOWN if none. */
i2m_format_t i2m_format_from_path(const char *path);

/** Checks before any work that @p path (and a Medit mesh's side file) can be written: a known
 *  extension, an existing writable directory, not a directory itself.  Writes nothing. */
i2m_err_t i2m_mesh_check_writable(const char *path);

/** The JSON side file written with a Medit mesh: "<path>.json" into out[cap] when @p path
 *  names a .mesh file (true); false for other formats or when it does not fit. */
bool i2m_mesh_side_path(const char *path, char *out, size_t cap);

/** Writes @p m to @p path in the format given by its extension.  Not collective.
 *  @p opts may be NULL (the defaults).  On error the message names the file and the
 *  problem (unknown extension, disk full). */
i2m_err_t i2m_mesh_write(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts);

/** Writes a distributed mesh (each rank's piece, with global vertex ids).  NAME.pvtu: every
 *  rank writes its piece NAME_<rank>.vtu beside it (its tets, material, the point array
 *  GlobalNodeId; no ghost cells) and rank 0 writes the .pvtu that names them.  Any other
 *  format: the pieces are stitched on rank 0 (vertices merged by global id), which writes the
 *  one file; *m on rank 0 is then the whole mesh.  Collective; the same error on every rank. */
i2m_err_t i2m_mesh_write_par(const i2m_par_t *par, i2m_tetmesh_t **m, const char *path, const i2m_write_opts_t *opts);

#ifdef __cplusplus
}
#endif
#endif
