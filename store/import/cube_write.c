/* store/import/cube_write.c - writing a cube set as one image file.
 *
 * Owns: st_cube_write (cube_io.h): the layout from st_cube_to_image (kinds/cube.h), the file
 * through st_image_write_img (image_io.h: its envmap and colour space kept). Does not own:
 * either of those.
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
    /* with the image's envmap (an EXR vertical strip gets envmap=cube and imports back as a
     * cube, as FETCH's does) and colour space */
    rc = st_image_write_img(path, &img, e);
    st_image_free(&img);
    return rc;
}
