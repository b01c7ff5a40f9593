/* store/import/cube_write.c - writing a cube set as one image file.
 *
 * Owns: st_cube_write (cube_io.h): the layout from st_cube_to_image (kinds/cube.h), the file
 * through st_image_write (image_io.h). Does not own: either of those.
 */
#include "cube_io.h"
#include "image_io.h"

int st_cube_write(const st_set *cube, unsigned level, st_cube_layout layout, const char *path,
                  st_error *e)
{
    st_image img;
    int rc = st_cube_to_image(cube, level, layout, &img, e);
    if (rc != ST_OK)
        return rc;
    rc = st_image_write(path, img.w, img.h, img.nchan, img.dtype, img.data, e);
    st_image_free(&img);
    return rc;
}
