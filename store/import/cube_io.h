/* store/import/cube_io.h - writing a cube set as one image file (cube_write.c).
 *
 * Owns: st_cube_write. Does not own: cube sets and their layouts (kinds/cube.h), image files
 * (image_io.h, through which it writes).
 */
#ifndef ST_CUBE_IO_H
#define ST_CUBE_IO_H

#include "cube.h"

/* Writes level `level` of a cube set as one image in `layout` (strip or cross; not latlong)
 * through st_image_write_img (format from the extension, e.g. .exr or .png; the set's colour
 * space recorded). An EXR vertical strip carries envmap=cube, so it imports back as the same
 * cube with no option; the other layouts carry no envmap tag (cube=auto or the layout's
 * option imports them). */
int st_cube_write(const st_set *cube, unsigned level, st_cube_layout layout, const char *path,
                  st_error *e);

#endif
