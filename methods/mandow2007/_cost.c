/* Mandow 2007 eq. (13), the GA's cost J(K), in C: a second implementation of
 * methods.mandow2007.segments.segment_cost (the numpy one is the reference; tests/methods/mandow2007/
 * test_cost_c.py checks the two agree to 1e-12 relative and that the GA picks the same chromosomes).
 *
 * For each parameter row K = (x_ICRl, x_ICRr, y_ICRv, alpha_l, alpha_r) and each segment: eqs. (6)-(7)
 * integrated exactly over the segment's intervals (SE(2) exponential, zero-order hold), in the frame of the
 * segment start, compared with the reference increment; J = sum of squared position and wrapped heading
 * residuals.  Rows are done two at a time in SSE2 lanes (cost_pair: each lane the operations of cost_row, so
 * the same bits as one row alone; tests/methods/mandow2007/test_ga.py checks a row's cost does not depend on its
 * batch), ~1.4x one row at a time.  The same per-interval arithmetic as segments._increments_chunk; the heading within a segment
 * starts at 1 instead of dividing the run's running heading by its value at the segment start, and sums run
 * in order: the last bits differ from numpy's (pairwise sums, running product over the whole run).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define SMALL_ANGLE 0.05

static int get_buf(PyObject *o, Py_buffer *b, const char *fmt, const char *what, int writable) {
    if (PyObject_GetBuffer(o, b, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)) < 0) return -1;
    if (b->ndim > 2 || strcmp(b->format, fmt) != 0) {
        PyErr_Format(PyExc_TypeError, "%s: expected a contiguous array of format '%s', got '%s'", what, fmt, b->format);
        PyBuffer_Release(b);
        return -1;
    }
    return 0;
}

/* Python's float %: the result takes the sign of the divisor (numpy's remainder) */
static inline double wrap_angle(double a) {
    const double two_pi = 2 * M_PI;
    double x = a + M_PI;
    double mod = fmod(x, two_pi);
    if (mod != 0.0) {
        if (mod < 0) mod += two_pi;
    } else {
        mod = 0.0;
    }
    return mod - M_PI;
}

/* eq. (13) for one parameter row (inf for a degenerate row, x_ICRr <= x_ICRl) */
static double cost_row(const double *kr, const double *dl, const double *dr, const int64_t *first, Py_ssize_t n,
                       Py_ssize_t m, const double *rdx, const double *rdy, const double *rdphi) {
    const double xl = kr[0], xr = kr[1], yv = kr[2], al = kr[3], ar = kr[4];
    if (!(xr > xl)) return INFINITY;
    const double inv = 1.0 / (xr - xl);
    const double th_l = -al * inv, th_r = ar * inv, f_l = xr * al * inv, f_r = -xl * ar * inv;
    double cost = 0.0;
    for (Py_ssize_t s = 0; s < n; s++) {
        const Py_ssize_t j0 = first[s], j1 = s + 1 < n ? first[s + 1] : m;
        double hr = 1.0, hi = 0.0, zr = 0.0, zi = 0.0, dphi = 0.0;
        for (Py_ssize_t j = j0; j < j1; j++) {
            const double dth = th_l * dl[j] + th_r * dr[j];
            const double fwd = f_l * dl[j] + f_r * dr[j];
            const double lat = -yv * dth;
            double sn, cs;
            if (fabs(dth) > SMALL_ANGLE) {
                sn = sin(dth) / dth;
                cs = (1.0 - cos(dth)) / dth;
            } else {
                const double d2 = dth * dth;
                sn = 1.0 + d2 * (-1.0 / 6 + d2 * (1.0 / 120 - d2 * (1.0 / 5040)));
                cs = dth * (0.5 + d2 * (-1.0 / 24 + d2 * (1.0 / 720 - d2 * (1.0 / 40320))));
            }
            const double br = sn * fwd - cs * lat, bi = cs * fwd + sn * lat;  /* body increment */
            zr += br * hr - bi * hi;
            zi += br * hi + bi * hr;
            const double rr = 1.0 - dth * cs, ri = dth * sn;  /* exp(i dth) */
            const double t = hr * rr - hi * ri;
            hi = hr * ri + hi * rr;
            hr = t;
            dphi += dth;
        }
        const double ex = rdx[s] - zr, ey = rdy[s] - zi, ephi = wrap_angle(rdphi[s] - dphi);
        cost += ex * ex + ey * ey + ephi * ephi;
    }
    return cost;
}

#ifdef __SSE2__
/* cost_row for two rows at once (SSE2 lanes): every lane does cost_row's operations in its order (IEEE add, sub, mul
 * per lane, no fused multiply-add), so the same bits as cost_row; a degenerate row runs on zeros and gives inf */
static void cost_pair(const double *k2, const double *dl, const double *dr, const int64_t *first, Py_ssize_t n,
                      Py_ssize_t m, const double *rdx, const double *rdy, const double *rdphi, double *out) {
    double thl[2], thr[2], fl[2], fr[2], nyv[2];
    int live[2];
    for (int b = 0; b < 2; b++) {
        const double *kr = k2 + 5 * b;
        const double xl = kr[0], xr = kr[1], yv = kr[2], al = kr[3], ar = kr[4];
        live[b] = xr > xl;
        const double inv = live[b] ? 1.0 / (xr - xl) : 0.0;
        thl[b] = live[b] ? -al * inv : 0.0;
        thr[b] = live[b] ? ar * inv : 0.0;
        fl[b] = live[b] ? xr * al * inv : 0.0;
        fr[b] = live[b] ? -xl * ar * inv : 0.0;
        nyv[b] = live[b] ? -yv : 0.0;
    }
    const __m128d v_thl = _mm_loadu_pd(thl), v_thr = _mm_loadu_pd(thr), v_fl = _mm_loadu_pd(fl), v_fr = _mm_loadu_pd(fr);
    const __m128d v_nyv = _mm_loadu_pd(nyv), one = _mm_set1_pd(1.0), half = _mm_set1_pd(0.5);
    const __m128d c6 = _mm_set1_pd(-1.0 / 6), c120 = _mm_set1_pd(1.0 / 120), c5040 = _mm_set1_pd(1.0 / 5040);
    const __m128d c24 = _mm_set1_pd(-1.0 / 24), c720 = _mm_set1_pd(1.0 / 720), c40320 = _mm_set1_pd(1.0 / 40320);
    const __m128d sign = _mm_set1_pd(-0.0), small = _mm_set1_pd(SMALL_ANGLE);
    double cost[2] = {0.0, 0.0};
    for (Py_ssize_t s = 0; s < n; s++) {
        const Py_ssize_t j0 = first[s], j1 = s + 1 < n ? first[s + 1] : m;
        __m128d hr = one, hi = _mm_setzero_pd(), zr = _mm_setzero_pd(), zi = _mm_setzero_pd(), dphi = _mm_setzero_pd();
        for (Py_ssize_t j = j0; j < j1; j++) {
            const __m128d vdl = _mm_set1_pd(dl[j]), vdr = _mm_set1_pd(dr[j]);
            const __m128d dth = _mm_add_pd(_mm_mul_pd(v_thl, vdl), _mm_mul_pd(v_thr, vdr));
            const __m128d fwd = _mm_add_pd(_mm_mul_pd(v_fl, vdl), _mm_mul_pd(v_fr, vdr));
            const __m128d lat = _mm_mul_pd(v_nyv, dth);
            const __m128d d2 = _mm_mul_pd(dth, dth);
            __m128d sn = _mm_add_pd(one, _mm_mul_pd(d2, _mm_add_pd(c6, _mm_mul_pd(d2, _mm_sub_pd(c120, _mm_mul_pd(d2, c5040))))));
            __m128d cs = _mm_mul_pd(dth, _mm_add_pd(half, _mm_mul_pd(d2, _mm_add_pd(c24, _mm_mul_pd(d2,
                                    _mm_sub_pd(c720, _mm_mul_pd(d2, c40320)))))));
            const int big = _mm_movemask_pd(_mm_cmpgt_pd(_mm_andnot_pd(sign, dth), small));
            if (big) {  /* rare: a turn beyond the series' range in one interval */
                double d[2], a[2], c[2];
                _mm_storeu_pd(d, dth);
                _mm_storeu_pd(a, sn);
                _mm_storeu_pd(c, cs);
                for (int b = 0; b < 2; b++)
                    if (big & (1 << b)) {
                        a[b] = sin(d[b]) / d[b];
                        c[b] = (1.0 - cos(d[b])) / d[b];
                    }
                sn = _mm_loadu_pd(a);
                cs = _mm_loadu_pd(c);
            }
            const __m128d br = _mm_sub_pd(_mm_mul_pd(sn, fwd), _mm_mul_pd(cs, lat));
            const __m128d bi = _mm_add_pd(_mm_mul_pd(cs, fwd), _mm_mul_pd(sn, lat));
            zr = _mm_add_pd(zr, _mm_sub_pd(_mm_mul_pd(br, hr), _mm_mul_pd(bi, hi)));
            zi = _mm_add_pd(zi, _mm_add_pd(_mm_mul_pd(br, hi), _mm_mul_pd(bi, hr)));
            const __m128d rr = _mm_sub_pd(one, _mm_mul_pd(dth, cs)), ri = _mm_mul_pd(dth, sn);
            const __m128d t = _mm_sub_pd(_mm_mul_pd(hr, rr), _mm_mul_pd(hi, ri));
            hi = _mm_add_pd(_mm_mul_pd(hr, ri), _mm_mul_pd(hi, rr));
            hr = t;
            dphi = _mm_add_pd(dphi, dth);
        }
        double a_zr[2], a_zi[2], a_dphi[2];
        _mm_storeu_pd(a_zr, zr);
        _mm_storeu_pd(a_zi, zi);
        _mm_storeu_pd(a_dphi, dphi);
        for (int b = 0; b < 2; b++) {
            const double ex = rdx[s] - a_zr[b], ey = rdy[s] - a_zi[b], ephi = wrap_angle(rdphi[s] - a_dphi[b]);
            cost[b] += ex * ex + ey * ey + ephi * ephi;
        }
    }
    for (int b = 0; b < 2; b++) out[b] = live[b] ? cost[b] : INFINITY;
}
#endif

/* segment_cost(k (P*5), dl (M), dr (M), first (N, int64), ref_dx, ref_dy, ref_dphi (N), out (P)) */
static PyObject *segment_cost(PyObject *self, PyObject *args) {
    enum { K, DL, DR, FIRST, DX, DY, DPHI, OUT, N_BUF };
    static const char *const names[N_BUF] = {"k", "dl", "dr", "first", "ref_dx", "ref_dy", "ref_dphi", "out"};
    PyObject *obj[N_BUF];
    Py_buffer buf[N_BUF];
    if (!PyArg_ParseTuple(args, "OOOOOOOO", &obj[K], &obj[DL], &obj[DR], &obj[FIRST], &obj[DX], &obj[DY], &obj[DPHI],
                          &obj[OUT]))
        return NULL;
    int got = 0;  /* buffers 0 .. got-1 are held */
    PyObject *ret = NULL;
    for (; got < N_BUF; got++) {
        /* float64 everywhere, int64 segment starts (numpy's format for it is 'l' on LP64, 'q' elsewhere), out writable */
        const int ok = got == FIRST ? (get_buf(obj[got], &buf[got], "l", names[got], 0) == 0 ||
                                       (PyErr_Clear(), get_buf(obj[got], &buf[got], "q", names[got], 0) == 0))
                                    : get_buf(obj[got], &buf[got], "d", names[got], got == OUT) == 0;
        if (!ok) goto done;
    }
    const Py_buffer bk = buf[K], bdl = buf[DL], bdr = buf[DR], bfirst = buf[FIRST], bdx = buf[DX], bdy = buf[DY],
                    bdphi = buf[DPHI], bout = buf[OUT];
    {
        Py_ssize_t m = bdl.len / (Py_ssize_t)sizeof(double), n = bfirst.len / (Py_ssize_t)sizeof(int64_t);
        Py_ssize_t p = bout.len / (Py_ssize_t)sizeof(double);
        if (bdr.len != bdl.len || bk.len != p * 5 * (Py_ssize_t)sizeof(double) ||
            bdx.len != n * (Py_ssize_t)sizeof(double) || bdy.len != bdx.len || bdphi.len != bdx.len ||
            bfirst.itemsize != (Py_ssize_t)sizeof(int64_t)) {
            PyErr_SetString(PyExc_ValueError, "segment_cost: inconsistent array sizes");
            goto done;
        }
        const double *k = bk.buf, *dl = bdl.buf, *dr = bdr.buf, *rdx = bdx.buf, *rdy = bdy.buf, *rdphi = bdphi.buf;
        const int64_t *first = bfirst.buf;
        double *out = bout.buf;
        for (Py_ssize_t i = 1; i < n; i++) {
            if (first[i] <= first[i - 1] || first[i] >= m) {
                PyErr_SetString(PyExc_ValueError, "segment_cost: segment starts must strictly increase within the intervals");
                goto done;
            }
        }
        if (n && (first[0] != 0 || first[n - 1] >= m)) {
            PyErr_SetString(PyExc_ValueError, "segment_cost: the first segment must start at interval 0");
            goto done;
        }
        Py_BEGIN_ALLOW_THREADS
        Py_ssize_t r = 0;
#ifdef __SSE2__
        for (; r + 1 < p; r += 2) cost_pair(k + 5 * r, dl, dr, first, n, m, rdx, rdy, rdphi, out + r);
#endif
        for (; r < p; r++) out[r] = cost_row(k + 5 * r, dl, dr, first, n, m, rdx, rdy, rdphi);
        Py_END_ALLOW_THREADS
        Py_INCREF(Py_None);
        ret = Py_None;
    }
done:
    while (got > 0) PyBuffer_Release(&buf[--got]);
    return ret;
}

static PyMethodDef methods[] = {
    {"segment_cost", segment_cost, METH_VARARGS, "Mandow 2007 eq. (13) for parameter rows (see segments.segment_cost)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef cost_module = {PyModuleDef_HEAD_INIT, "_cost", "Mandow 2007 eq. (13) in C", -1, methods};

PyMODINIT_FUNC PyInit__cost(void) { return PyModule_Create(&cost_module); }
