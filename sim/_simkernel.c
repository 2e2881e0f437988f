/* Compiled simulator kernel: the IMU model's Gauss-Markov block filter and its per-sample output,
 * operation for operation the Python references in sim/imu.py (first_order_filter_python,
 * imu_output_python). Loaded through sim/kernel.py; README, "Compiled simulator kernel".
 *
 * Bit identity with CPython (and, for the filter, with scipy.signal.lfilter, which the reference
 * reproduces) is the contract, so, as in fusion/_strapdown.c:
 * - every expression keeps the Python's evaluation order and parenthesisation, each operation
 *   rounded to double;
 * - built with -ffp-contract=off (no fused multiply-add), never -ffast-math or -march=native
 *   (setup.py);
 * - Python's errors are reproduced where the reference raises them: round() of an infinite or
 *   NaN quotient raises OverflowError / ValueError with CPython's messages, in the reference's
 *   order;
 * - only exact floats in exact tuples / lists (and float64 buffers for the filter) take this
 *   path: anything else (ints, numpy scalars, other sequences, keyword arguments, wrong lengths,
 *   other dtypes, overlapping input and output) calls the bound Python reference, which then
 *   raises or computes exactly as it always did. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

static PyObject *filter_ref = NULL; /* sim.imu.first_order_filter_python */
static PyObject *output_ref = NULL; /* sim.imu.imu_output_python */

#define MAX_COLUMNS 64

/* Values of an exact tuple or list of exactly n exact floats into out; 0 if it is not one. */
static int
floats_of(PyObject *seq, double *out, Py_ssize_t n)
{
    PyObject **items;
    if (PyTuple_CheckExact(seq)) {
        if (PyTuple_GET_SIZE(seq) != n) {
            return 0;
        }
        items = &PyTuple_GET_ITEM(seq, 0);
    }
    else if (PyList_CheckExact(seq)) {
        if (PyList_GET_SIZE(seq) != n) {
            return 0;
        }
        items = ((PyListObject *)seq)->ob_item;
    }
    else {
        return 0;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        if (!PyFloat_CheckExact(items[i])) {
            return 0;
        }
        out[i] = PyFloat_AS_DOUBLE(items[i]);
    }
    return 1;
}

/* Length of an exact tuple or list, or -1. */
static Py_ssize_t
seq_len(PyObject *seq)
{
    if (PyTuple_CheckExact(seq)) {
        return PyTuple_GET_SIZE(seq);
    }
    if (PyList_CheckExact(seq)) {
        return PyList_GET_SIZE(seq);
    }
    return -1;
}

static int
is_float64_2d(const Py_buffer *b)
{
    return b->ndim == 2 && b->itemsize == 8 && b->format != NULL
           && (strcmp(b->format, "d") == 0 || strcmp(b->format, "=d") == 0
               || strcmp(b->format, "@d") == 0);
}

/* The bytes [lo, hi) that a 2-D buffer touches. */
static void
span(const Py_buffer *b, char **lo, char **hi)
{
    char *a = (char *)b->buf, *z = (char *)b->buf;
    for (int d = 0; d < 2; d++) {
        Py_ssize_t ext = (b->shape[d] - 1) * b->strides[d];
        if (ext < 0) {
            a += ext;
        }
        else {
            z += ext;
        }
    }
    *lo = a;
    *hi = z + b->itemsize;
}

PyDoc_STRVAR(first_order_filter_doc,
"first_order_filter(x, b0, a1, zi, out)\n--\n\n"
"scipy.signal.lfilter([b0[j]], [1.0, a1[j]], x[:, j], zi=[zi[j]])[0] into out[:, j]:\n"
":func:`sim.imu.first_order_filter_python`, bit for bit.");

static PyObject *
first_order_filter(PyObject *module, PyObject *const *args, Py_ssize_t nargsf,
                   PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double b[MAX_COLUMNS], a[MAX_COLUMNS], z[MAX_COLUMNS];
    Py_buffer xb, ob;
    int have_x = 0, have_o = 0, ok = 0;
    Py_ssize_t k = -1;
    if (filter_ref == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "sim._simkernel.bind_imu() was not called");
        return NULL;
    }
    if (kwnames == NULL && nargs == 5) {
        k = seq_len(args[3]);
    }
    if (k >= 1 && k <= MAX_COLUMNS && floats_of(args[1], b, k) && floats_of(args[2], a, k)
        && floats_of(args[3], z, k)) {
        if (PyObject_GetBuffer(args[0], &xb, PyBUF_STRIDES | PyBUF_FORMAT) == 0) {
            have_x = 1;
        }
        else {
            PyErr_Clear();
        }
        if (have_x
            && PyObject_GetBuffer(args[4], &ob, PyBUF_STRIDES | PyBUF_FORMAT | PyBUF_WRITABLE)
                   == 0) {
            have_o = 1;
        }
        else {
            PyErr_Clear();
        }
        if (have_o && is_float64_2d(&xb) && is_float64_2d(&ob) && xb.shape[1] == k
            && ob.shape[1] == k && xb.shape[0] == ob.shape[0]) {
            ok = 1;
            if (xb.shape[0] > 0) {
                char *xl, *xh, *ol, *oh;
                span(&xb, &xl, &xh);
                span(&ob, &ol, &oh);
                /* the reference reads all of x before it writes: the same elements in place are
                 * fine, any other overlap goes to it */
                if (xl < oh && ol < xh
                    && !(xb.buf == ob.buf && xb.strides[0] == ob.strides[0]
                         && xb.strides[1] == ob.strides[1])) {
                    ok = 0;
                }
            }
        }
    }
    if (!ok) {
        if (have_o) {
            PyBuffer_Release(&ob);
        }
        if (have_x) {
            PyBuffer_Release(&xb);
        }
        return PyObject_Vectorcall(filter_ref, args, nargsf, kwnames);
    }
    const Py_ssize_t n = xb.shape[0];
    for (Py_ssize_t i = 0; i < n; i++) {
        const char *xr = (const char *)xb.buf + i * xb.strides[0];
        char *orow = (char *)ob.buf + i * ob.strides[0];
        for (Py_ssize_t j = 0; j < k; j++) {
            const double xv = *(const double *)(xr + j * xb.strides[1]);
            const double y = z[j] + b[j] * xv;
            z[j] = xv * 0.0 - y * a[j];
            *(double *)(orow + j * ob.strides[1]) = y;
        }
    }
    PyBuffer_Release(&ob);
    PyBuffer_Release(&xb);
    Py_RETURN_NONE;
}

/* round(v / q) * q as CPython computes it: float.__round__ (round half to even, through
 * PyLong_FromDouble, so an infinite or NaN quotient raises and a zero is +0.0), then
 * int * float. */
static int
quantise(double *v, double q)
{
    const double x = *v / q;
    double rounded = round(x);
    if (fabs(x - rounded) == 0.5) {
        rounded = 2.0 * round(x / 2.0);
    }
    if (isinf(rounded)) {
        PyErr_SetString(PyExc_OverflowError, "cannot convert float infinity to integer");
        return -1;
    }
    if (isnan(rounded)) {
        PyErr_SetString(PyExc_ValueError, "cannot convert float NaN to integer");
        return -1;
    }
    if (rounded == 0.0) {
        rounded = 0.0; /* the int 0 has no sign */
    }
    *v = rounded * q;
    return 0;
}

static double
saturate(double y, double r)
{
    return y > r ? r : y < -r ? -r : y;
}

PyDoc_STRVAR(imu_output_doc,
"imu_output(u, e, p)\n--\n\n"
"One IMU output: :func:`sim.imu.imu_output_python`, bit for bit.");

static PyObject *
imu_output(PyObject *module, PyObject *const *args, Py_ssize_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    double u[6], e[6], p[22], y[6];
    if (output_ref == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "sim._simkernel.bind_imu() was not called");
        return NULL;
    }
    if (kwnames != NULL || nargs != 3 || !floats_of(args[0], u, 6) || !floats_of(args[1], e, 6)
        || !floats_of(args[2], p, 22)) {
        return PyObject_Vectorcall(output_ref, args, nargsf, kwnames);
    }
    const double *ta = p, *tg = p + 9;
    y[0] = ta[0] * u[0] + ta[1] * u[1] + ta[2] * u[2] + e[0];
    y[1] = ta[3] * u[0] + ta[4] * u[1] + ta[5] * u[2] + e[1];
    y[2] = ta[6] * u[0] + ta[7] * u[1] + ta[8] * u[2] + e[2];
    y[3] = tg[0] * u[3] + tg[1] * u[4] + tg[2] * u[5] + e[3];
    y[4] = tg[3] * u[3] + tg[4] * u[4] + tg[5] * u[5] + e[4];
    y[5] = tg[6] * u[3] + tg[7] * u[4] + tg[8] * u[5] + e[5];
    for (int i = 0; i < 6; i++) {
        y[i] = saturate(y[i], i < 3 ? p[18] : p[19]);
    }
    for (int t = 0; t < 2; t++) {
        const double q = p[20 + t];
        if (q > 0.0) {
            for (int i = 3 * t; i < 3 * t + 3; i++) {
                if (quantise(&y[i], q) < 0) {
                    return NULL;
                }
            }
        }
    }
    PyObject *out = PyList_New(6);
    if (out == NULL) {
        return NULL;
    }
    for (int i = 0; i < 6; i++) {
        PyObject *f = PyFloat_FromDouble(y[i]);
        if (f == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, i, f);
    }
    return out;
}

PyDoc_STRVAR(bind_imu_doc,
"bind_imu(first_order_filter_ref, imu_output_ref)\n--\n\n"
"The Python references the kernel calls for inputs it does not take (sim.kernel does this).");

static PyObject *
bind_imu(PyObject *module, PyObject *args)
{
    PyObject *f, *o;
    if (!PyArg_ParseTuple(args, "OO:bind_imu", &f, &o)) {
        return NULL;
    }
    if (!PyCallable_Check(f) || !PyCallable_Check(o)) {
        PyErr_SetString(PyExc_TypeError, "bind_imu: the references must be callable");
        return NULL;
    }
    Py_INCREF(f);
    Py_INCREF(o);
    Py_XSETREF(filter_ref, f);
    Py_XSETREF(output_ref, o);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"first_order_filter", (PyCFunction)(void (*)(void))first_order_filter,
     METH_FASTCALL | METH_KEYWORDS, first_order_filter_doc},
    {"imu_output", (PyCFunction)(void (*)(void))imu_output, METH_FASTCALL | METH_KEYWORDS,
     imu_output_doc},
    {"bind_imu", bind_imu, METH_VARARGS, bind_imu_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    "sim._simkernel",
    "Compiled simulator kernel, bit for bit the Python references in sim.imu.",
    -1,
    methods,
};

PyMODINIT_FUNC
PyInit__simkernel(void)
{
    return PyModule_Create(&module_def);
}
