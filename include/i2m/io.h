/* i2m io layer (layer 7): mesh writers.  The format follows the output file's extension:
 *   .vtu   VTK XML unstructured grid, binary appended data (zlib-compressed unless
 *          i2m_write_opts_t.compress is false), cell data "material"; with the companion
 *          NAME.interfaces.vtu: the interface triangles, cell data "label_a" < "label_b"
 *          (the labels on the two sides; normal from a to b)
 *   .mesh  Medit ASCII: vertices, tetrahedra (ref = label value), interface triangles
 *          (ref = interface number; a comment block maps numbers to label pairs, and so does
 *          the JSON side file NAME.mesh.json written with it, which survives tools such as
 *          mmg that drop comments)
 *   .msh   Gmsh 4.1 or 2.2 (i2m_write_opts_t.msh_version), binary, or ASCII with
 *          i2m_write_opts_t.ascii or the environment variable I2M_MSH_ASCII=1: one physical
 *          volume per label (tag v > 0, named by its tissue name from opts->names, else
 *          "label_<v>"), one physical surface per interface pair ("interface_<a>_<b>", tags
 *          after the largest label); in 4.1 each volume entity lists its bounding surfaces.
 * Interface triangles (Medit, Gmsh, the VTU interfaces file) follow i2m_tetmesh_t: the label
 * pair (a, b) has the lower label first (the background 0, then tissues by value) and the
 * normal (right-hand rule) points from b to a, from the higher label to the lower: out of the
 * meshed domain on the outer boundary, as Medit, mmg and Gmsh expect of a boundary surface.
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
  bool compress;                  /**< VTU: zlib-compressed appended data (default true;
                                       false: raw) */
} i2m_write_opts_t;

/** The default write options. */
i2m_write_opts_t i2m_write_opts_default(void);

/** Format for a file name (by extension, case-insensitive); I2M_FORMAT_UNKNOWN if none. */
i2m_format_t i2m_format_from_path(const char *path);

/** Checks before any work that @p path (and a Medit mesh's side file) can be written: a known
 *  extension, an existing writable directory, not a directory itself.  Writes nothing. */
i2m_err_t i2m_mesh_check_writable(const char *path);

/** The companion file of interface triangles that a .vtu or .pvtu output comes with:
 *  NAME.interfaces.vtu (.pvtu) into @p out.  false for other formats or when @p cap is too
 *  small. */
bool i2m_mesh_interfaces_path(const char *path, char *out, size_t cap);

/** The JSON side file written with a Medit mesh: "<path>.json" into out[cap] when @p path
 *  names a .mesh file (true); false for other formats or when it does not fit. */
bool i2m_mesh_side_path(const char *path, char *out, size_t cap);

/** Writes @p m to @p path in the format given by its extension (a .vtu: and its interfaces
 *  file, see i2m_mesh_interfaces_path; a .mesh: and its side file).  Not collective.
 *  @p opts may be NULL (the defaults).  On error the message names the file and the
 *  problem (unknown extension, disk full). */
i2m_err_t i2m_mesh_write(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts);

/** Writes a distributed mesh (each rank's piece, with global vertex ids).  NAME.pvtu: every
 *  rank writes its piece NAME_<rank>.vtu beside it (its tets, material, the point array
 *  GlobalNodeId; no ghost cells) and NAME_<rank>.interfaces.vtu (its interface triangles),
 *  and rank 0 writes NAME.pvtu and NAME.interfaces.pvtu that name them.  Any other
 *  format: the pieces are stitched on rank 0 (vertices merged by global id), which writes the
 *  one file; *m on rank 0 is then the whole mesh.  Collective; the same error on every rank. */
i2m_err_t i2m_mesh_write_par(const i2m_par_t *par, i2m_tetmesh_t **m, const char *path, const i2m_write_opts_t *opts);

#ifdef __cplusplus
}
#endif
#endif
