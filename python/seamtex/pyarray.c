/* python/seamtex/pyarray.c - seamtex.Array: a read-write, C-contiguous array of one or two
 * dimensions that exports the buffer protocol (PEP 3118: format, shape, strides), so that
 * sample results need no numpy. numpy.asarray(a), memoryview(a) and array-aware libraries see
 * its shape and type without a copy.
 *
 * Owns: one malloc'd block (freed with the Array), its format ("f", "B", "H", "I"), shape and
 * strides; the choice between returning an Array and a numpy array (st_py_array_out).
 * Does not own: what the values mean (pysample.c).
 */
#include "pyseamtex.h"

#include <stdlib.h>

typedef struct st_py_array {
    PyObject_HEAD
    void       *data;
    char        format[4];
    Py_ssize_t  itemsize;
    int         ndim;
    Py_ssize_t  shape[2];
    Py_ssize_t  strides[2];
    Py_ssize_t  exports;      /* buffers handed out and not released */
} st_py_array;

PyObject *st_py_array_wrap(void *data, const char *format, Py_ssize_t itemsize, int ndim,
                           Py_ssize_t n0, Py_ssize_t n1)
{
    st_py_array *a = PyObject_New(st_py_array, &st_py_array_type);
    if (!a) {
        free(data);
        return NULL;
    }
    a->data = data;
    snprintf(a->format, sizeof a->format, "%s", format);
    a->itemsize = itemsize;
    a->ndim = ndim;
    a->shape[0] = n0;
    a->shape[1] = ndim == 2 ? n1 : 1;
    a->strides[1] = itemsize;
    a->strides[0] = ndim == 2 ? n1 * itemsize : itemsize;
    a->exports = 0;
    return (PyObject *)a;
}

static void array_dealloc(st_py_array *a)
{
    free(a->data);
    PyObject_Free(a);
}

static int array_getbuffer(st_py_array *a, Py_buffer *view, int flags)
{
    view->obj = (PyObject *)a;
    Py_INCREF(a);
    view->buf = a->data;
    view->len = a->shape[0] * (a->ndim == 2 ? a->shape[1] : 1) * a->itemsize;
    view->readonly = 0;
    view->itemsize = a->itemsize;
    view->format = (flags & PyBUF_FORMAT) ? a->format : NULL;
    view->ndim = a->ndim;
    view->shape = (flags & PyBUF_ND) == PyBUF_ND ? a->shape : NULL;
    view->strides = (flags & PyBUF_STRIDES) == PyBUF_STRIDES ? a->strides : NULL;
    view->suboffsets = NULL;
    view->internal = NULL;
    /* without shape a consumer sees the bytes as one flat run: fine, the block is
     * contiguous */
    a->exports++;
    return 0;
}

static void array_releasebuffer(st_py_array *a, Py_buffer *view)
{
    (void)view;
    a->exports--;
}

static PyBufferProcs array_as_buffer = {
    (getbufferproc)array_getbuffer,
    (releasebufferproc)array_releasebuffer,
};

static Py_ssize_t array_len(st_py_array *a)
{
    return a->shape[0];
}

static PySequenceMethods array_as_sequence = {
    .sq_length = (lenfunc)array_len,
};

static PyObject *array_get_shape(st_py_array *a, void *closure)
{
    (void)closure;
    return a->ndim == 2 ? Py_BuildValue("(nn)", a->shape[0], a->shape[1])
                        : Py_BuildValue("(n)", a->shape[0]);
}

static PyObject *array_get_format(st_py_array *a, void *closure)
{
    (void)closure;
    return PyUnicode_FromString(a->format);
}

static PyObject *array_get_nbytes(st_py_array *a, void *closure)
{
    (void)closure;
    return PyLong_FromSsize_t(a->shape[0] * (a->ndim == 2 ? a->shape[1] : 1) * a->itemsize);
}

static PyObject *array_tolist(st_py_array *a, PyObject *unused)
{
    (void)unused;
    PyObject *mv = PyMemoryView_FromObject((PyObject *)a), *l;
    if (!mv)
        return NULL;
    l = PyObject_CallMethod(mv, "tolist", NULL);
    Py_DECREF(mv);
    return l;
}

static PyObject *array_repr(st_py_array *a)
{
    if (a->ndim == 2)
        return PyUnicode_FromFormat("<seamtex.Array format '%s' shape (%zd, %zd)>", a->format,
                                    a->shape[0], a->shape[1]);
    return PyUnicode_FromFormat("<seamtex.Array format '%s' shape (%zd,)>", a->format,
                                a->shape[0]);
}

static PyGetSetDef array_getset[] = {
    {"shape", (getter)array_get_shape, NULL, "The shape: (n,) or (n, nchan).", NULL},
    {"format", (getter)array_get_format, NULL,
     "The struct format of one item: 'f' float32, 'B' uint8, 'H' uint16.", NULL},
    {"nbytes", (getter)array_get_nbytes, NULL, "Size of the data in bytes.", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyMethodDef array_methods[] = {
    {"tolist", (PyCFunction)array_tolist, METH_NOARGS,
     "tolist() -> list\n\nThe values as (nested) Python lists."},
    {NULL, NULL, 0, NULL},
};

PyTypeObject st_py_array_type = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "seamtex.Array",
    .tp_basicsize = sizeof(st_py_array),
    .tp_dealloc = (destructor)array_dealloc,
    .tp_repr = (reprfunc)array_repr,
    .tp_as_sequence = &array_as_sequence,
    .tp_as_buffer = &array_as_buffer,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A result array of seamtex (values, coverage or per-query status) when numpy is\n"
              "not used. It supports the buffer protocol with its format and shape:\n"
              "memoryview(a), numpy.asarray(a) (no copy), a.tolist(), len(a), a.shape.",
    .tp_methods = array_methods,
    .tp_getset = array_getset,
};

/* numpy.asarray, imported on first use; Py_None when numpy is not importable */
static PyObject *g_asarray;

PyObject *st_py_array_out(st_py_client *self, PyObject *obj)
{
    if (!obj || self->numpy == 0 || !PyObject_TypeCheck(obj, &st_py_array_type))
        return obj;
    if (!g_asarray) {
        PyObject *np = PyImport_ImportModule("numpy");
        if (np) {
            g_asarray = PyObject_GetAttrString(np, "asarray");
            Py_DECREF(np);
        }
        if (!g_asarray) {
            PyErr_Clear();
            g_asarray = Py_None;
            Py_INCREF(g_asarray);
        }
    }
    if (g_asarray == Py_None) {
        if (self->numpy == 1) {
            Py_DECREF(obj);
            PyErr_SetString(PyExc_ImportError, "numpy=True but numpy cannot be imported");
            return NULL;
        }
        return obj;
    }
    PyObject *r = PyObject_CallOneArg(g_asarray, obj);
    Py_DECREF(obj);
    return r;
}
