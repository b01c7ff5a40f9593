/* render/camera.c - the camera orbit of seamtex-render and its perspective projection.
 *
 * Owns: frame i of an orbit (eye on a circle around the mesh's bounding box, looking at its
 * centre, y up) and the projection of a point to pixels. Does not own: rasterising.
 */
#include "render.h"

#include <math.h>

static void normalize(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0)
        for (int k = 0; k < 3; k++)
            v[k] /= l;
}

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

void rc_orbit_camera(const rc_orbit *o, const rm_mesh *m, unsigned i, unsigned width,
                     unsigned height, rc_camera *cam)
{
    double c[3], r = 0;
    for (int k = 0; k < 3; k++) {
        c[k] = 0.5 * ((double)m->bmin[k] + m->bmax[k]);
        double h = 0.5 * ((double)m->bmax[k] - m->bmin[k]);
        r += h * h;
    }
    r = sqrt(r);
    if (r <= 0)
        r = 1;
    double fov = o->fov_deg * M_PI / 180.0;
    /* at dist 1 the bounding sphere just fits the smaller of the two fields of view */
    double half = 0.5 * fov;
    double aspect = height ? (double)width / height : 1.0;
    if (aspect < 1)
        half = atan(tan(half) * aspect);
    double d = o->dist * r / sin(half);
    double az = (o->azim0_deg + 360.0 * (o->frames ? (double)i / o->frames : 0)) * M_PI / 180.0;
    double el = o->elev_deg * M_PI / 180.0;
    cam->eye[0] = c[0] + d * cos(el) * sin(az);
    cam->eye[1] = c[1] + d * sin(el);
    cam->eye[2] = c[2] + d * cos(el) * cos(az);
    for (int k = 0; k < 3; k++)
        cam->fwd[k] = c[k] - cam->eye[k];
    normalize(cam->fwd);
    double up[3] = { 0, 1, 0 };
    cross(cam->fwd, up, cam->right);
    normalize(cam->right);
    cross(cam->right, cam->fwd, cam->up);
    cam->focal = 1.0 / tan(0.5 * fov);
    cam->aspect = aspect;
    cam->znear = 1e-3 * r;
}

int rr_project(const rc_camera *cam, unsigned width, unsigned height, const float p[3],
               double *x, double *y, double *iw)
{
    double d[3] = { p[0] - cam->eye[0], p[1] - cam->eye[1], p[2] - cam->eye[2] };
    double vx = d[0] * cam->right[0] + d[1] * cam->right[1] + d[2] * cam->right[2];
    double vy = d[0] * cam->up[0] + d[1] * cam->up[1] + d[2] * cam->up[2];
    double vz = d[0] * cam->fwd[0] + d[1] * cam->fwd[1] + d[2] * cam->fwd[2];
    if (!(vz > cam->znear))
        return 0;
    double ndx = cam->focal / cam->aspect * vx / vz;
    double ndy = cam->focal * vy / vz;
    *x = (ndx * 0.5 + 0.5) * width;
    *y = (0.5 - ndy * 0.5) * height;
    *iw = 1.0 / vz;
    return 1;
}
