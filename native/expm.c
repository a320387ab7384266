/* The matrix exponential of the native plants' zero-order hold, computed at initialization
 * (the parameters may change before it): scaling and squaring with a [m/m] Pade approximant
 * (N. J. Higham, "The scaling and squaring method for the matrix exponential revisited",
 * SIAM J. Matrix Anal. Appl. 26(4), 2005, Algorithm 2.3), in the same order of operations as
 * the Python FMUs (dronefly/models/linear_algebra.py): every sum of products correctly
 * rounded (fmu_fsum), so both give the same floats. The tests cross-check it against
 * scipy.linalg.expm.
 */
#include "exact.h"
#include <math.h>
#include <string.h>
#include "expm.h"

/* Correctly rounded sum (Shewchuk's exact partial sums, then one rounding, half-even); the
 * plain sum where an intermediate or a term is not finite (the Python falls back the same). */
double fmu_fsum(const double *x, size_t n) {
    double partials[64];
    size_t np = 0;
    double plain = 0.0;
    for (size_t k = 0; k < n; k++) plain += x[k];
    for (size_t k = 0; k < n; k++) {
        double v = x[k];
        if (!isfinite(v)) return plain;
        size_t i = 0;
        for (size_t j = 0; j < np; j++) {
            double y = partials[j];
            if (fabs(v) < fabs(y)) { double t = v; v = y; y = t; }
            double hi = v + y;
            double lo = y - (hi - v);
            if (lo != 0.0) partials[i++] = lo;
            v = hi;
        }
        if (!isfinite(v)) return plain; /* an intermediate overflowed */
        if (i >= 64) return plain;      /* (cannot happen: at most 40 partials for doubles) */
        partials[i] = v;
        np = i + 1;
    }
    if (np == 0) return 0.0;
    size_t m = np;
    double hi = partials[--m], lo = 0.0;
    while (m > 0) {
        double v = hi, y = partials[--m];
        hi = v + y;
        double yr = hi - v;
        lo = y - yr;
        if (lo != 0.0) break;
    }
    /* round half to even: a tie in the last partial sum decided by the next one */
    if (m > 0 && ((lo < 0.0 && partials[m - 1] < 0.0) || (lo > 0.0 && partials[m - 1] > 0.0))) {
        double y = lo * 2.0;
        double v = hi + y;
        double yr = v - hi;
        if (y == yr) hi = v;
    }
    return hi;
}

#define N EXPM_MAX
typedef double Mat[N][N];

static void matmul(int n, const Mat a, const Mat b, Mat out) {
    Mat r;
    double terms[N];
    memset(r, 0, sizeof r);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            for (int k = 0; k < n; k++) terms[k] = a[i][k] * b[k][j];
            r[i][j] = fmu_fsum(terms, (size_t)n);
        }
    memcpy(out, r, sizeof r);
}

static double norm1(int n, const Mat a) {
    double best = 0.0, terms[N];
    int first = 1;
    for (int j = 0; j < n; j++) {
        for (int i = 0; i < n; i++) terms[i] = fabs(a[i][j]);
        double s = fmu_fsum(terms, (size_t)n);
        if (first || s > best) best = s; /* (Python's max keeps the first of equals) */
        first = 0;
    }
    return best;
}

/* out = sum_k c[k] * M[k], entry by entry in the given order */
static void combine(int n, int count, const double *c, const Mat *const *m, Mat out) {
    double terms[16];
    Mat r;
    memset(r, 0, sizeof r);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            for (int k = 0; k < count; k++) terms[k] = c[k] * (*m[k])[i][j];
            r[i][j] = fmu_fsum(terms, (size_t)count);
        }
    memcpy(out, r, sizeof r);
}

/* x = a^-1 b by Gaussian elimination with partial pivoting (the first largest pivot) */
static void solve(int n, const Mat a, const Mat b, Mat x) {
    Mat lu;
    memcpy(lu, a, sizeof lu);
    memcpy(x, b, sizeof lu);
    for (int k = 0; k < n; k++) {
        int p = k;
        for (int i = k + 1; i < n; i++)
            if (fabs(lu[i][k]) > fabs(lu[p][k])) p = i;
        if (p != k) {
            double t[N];
            memcpy(t, lu[k], sizeof t); memcpy(lu[k], lu[p], sizeof t); memcpy(lu[p], t, sizeof t);
            memcpy(t, x[k], sizeof t); memcpy(x[k], x[p], sizeof t); memcpy(x[p], t, sizeof t);
        }
        double pivot = lu[k][k];
        for (int i = k + 1; i < n; i++) {
            double f = lu[i][k] / pivot;
            if (f != 0.0) {
                for (int j = k + 1; j < n; j++) lu[i][j] -= f * lu[k][j];
                for (int j = 0; j < n; j++) x[i][j] -= f * x[k][j];
            }
        }
    }
    for (int k = n - 1; k >= 0; k--) {
        double pivot = lu[k][k];
        for (int j = 0; j < n; j++) {
            double s = x[k][j];
            for (int i = k + 1; i < n; i++) s -= lu[k][i] * x[i][j];
            x[k][j] = s / pivot;
        }
    }
}

static const double THETA[4] = {1.495585217958292e-2, 2.539398330063230e-1,
                                9.504178996162932e-1, 2.097847961257068e0};
static const int DEGREE[4] = {3, 5, 7, 9};
static const double THETA13 = 5.371920351148152e0;
static const double B3[] = {120.0, 60.0, 12.0, 1.0};
static const double B5[] = {30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0};
static const double B7[] = {17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0,
                            56.0, 1.0};
static const double B9[] = {17643225600.0, 8821612800.0, 2075673600.0, 302702400.0,
                            30270240.0, 2162160.0, 110880.0, 3960.0, 90.0, 1.0};
static const double B13[] = {64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
                             1187353796428800.0, 129060195264000.0, 10559470521600.0,
                             670442572800.0, 33522128640.0, 1323241920.0, 40840800.0,
                             960960.0, 16380.0, 182.0, 1.0};

static void identity(int n, Mat e) {
    memset(e, 0, sizeof(Mat));
    for (int i = 0; i < n; i++) e[i][i] = 1.0;
}

/* u, v: the odd and even parts of p_m(a) */
static void pade(int n, const Mat a, int m, Mat u, Mat v) {
    Mat eye, a2;
    identity(n, eye);
    matmul(n, a, a, a2);
    if (m < 13) {
        const double *b = m == 3 ? B3 : m == 5 ? B5 : m == 7 ? B7 : B9;
        Mat powers[5];
        const Mat *ptr[5];
        double cu[5], cv[5];
        int count = (m + 1) / 2;
        memcpy(powers[0], eye, sizeof(Mat));
        memcpy(powers[1], a2, sizeof(Mat));
        for (int k = 2; k < count; k++) matmul(n, powers[k - 1], a2, powers[k]);
        for (int k = 0; k < count; k++) {
            ptr[k] = (const Mat *)&powers[k];
            cu[k] = b[2 * k + 1];
            cv[k] = b[2 * k];
        }
        Mat t;
        combine(n, count, cu, ptr, t);
        matmul(n, a, t, u);
        combine(n, count, cv, ptr, v);
        return;
    }
    const double *b = B13;
    Mat a4, a6, t, inner;
    matmul(n, a2, a2, a4);
    matmul(n, a4, a2, a6);
    {
        const Mat *p[3] = {(const Mat *)&a6, (const Mat *)&a4, (const Mat *)&a2};
        double cc[3] = {b[13], b[11], b[9]};
        combine(n, 3, cc, p, t);
        matmul(n, a6, t, inner);
    }
    {
        const Mat *p[5] = {(const Mat *)&inner, (const Mat *)&a6, (const Mat *)&a4,
                           (const Mat *)&a2, (const Mat *)&eye};
        double cc[5] = {1.0, b[7], b[5], b[3], b[1]};
        combine(n, 5, cc, p, t);
        matmul(n, a, t, u);
    }
    {
        const Mat *p[3] = {(const Mat *)&a6, (const Mat *)&a4, (const Mat *)&a2};
        double cc[3] = {b[12], b[10], b[8]};
        combine(n, 3, cc, p, t);
        matmul(n, a6, t, inner);
    }
    {
        const Mat *p[5] = {(const Mat *)&inner, (const Mat *)&a6, (const Mat *)&a4,
                           (const Mat *)&a2, (const Mat *)&eye};
        double cc[5] = {1.0, b[6], b[4], b[2], b[0]};
        combine(n, 5, cc, p, v);
    }
}

static void rational(int n, const Mat u, const Mat v, Mat r) {
    Mat num, den;
    const Mat *p[2] = {(const Mat *)v, (const Mat *)u};
    double minus[2] = {1.0, -1.0}, plus[2] = {1.0, 1.0};
    combine(n, 2, minus, p, den);
    combine(n, 2, plus, p, num);
    solve(n, den, num, r);
}

void fmu_expm(const double *a, int n, double *e) {
    Mat rows, u, v, r;
    memset(rows, 0, sizeof rows);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) rows[i][j] = a[i * n + j];
    double norm = norm1(n, rows);
    int done = 0;
    for (int k = 0; k < 4 && !done; k++) {
        if (norm <= THETA[k]) {
            pade(n, rows, DEGREE[k], u, v);
            rational(n, u, v, r);
            done = 1;
        }
    }
    if (!done) {
        int s;
        if (isinf(norm)) { /* finite entries whose column sum overflows: n max|a| bounds it */
            double big = 0.0;
            for (int i = 0; i < n; i++)
                for (int j = 0; j < n; j++) big = fmax(big, fabs(rows[i][j]));
            s = (int)ceil(log2((double)n) + log2(big) - log2(THETA13));
        } else {
            s = norm > THETA13 ? (int)ceil(log2(norm / THETA13)) : 0;
        }
        if (s < 0) s = 0;
        Mat scaled;
        memset(scaled, 0, sizeof scaled);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) scaled[i][j] = ldexp(rows[i][j], -s);
        pade(n, scaled, 13, u, v);
        rational(n, u, v, r);
        for (int k = 0; k < s; k++) {
            matmul(n, r, r, r);
            int finite = 1;
            for (int i = 0; i < n; i++)
                for (int j = 0; j < n; j++) finite = finite && isfinite(r[i][j]);
            if (!finite) break;
        }
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) e[i * n + j] = r[i][j];
}

/* 1-norm of the rows x cols block at a (row stride `stride`) times 2^NORM_SHIFT: finite for
 * finite entries, at most EXPM_MAX rows (the Python's _shifted_norm, the same sums) */
#define NORM_SHIFT (-11)
static double shifted_norm(const double *a, int rows, int cols, int stride) {
    double best = 0.0, terms[N];
    for (int j = 0; j < cols; j++) {
        for (int i = 0; i < rows; i++) terms[i] = ldexp(fabs(a[i * stride + j]), NORM_SHIFT);
        double s = fmu_fsum(terms, (size_t)rows);
        if (j == 0 || s > best) best = s;
    }
    return best;
}

/* The blocks of exp([[A h, B h], [0, 0]]), the Python's hold_exponential operation for
 * operation: B h scaled by 2^-k, the least k for which its 1-norm does not raise the
 * squarings that A h alone needs (at most theta_13 2^s_A), and Gamma scaled back by 2^k
 * (exact in binary floating point; k = 0 wherever B h does not exceed that bound). */
void fmu_expm_hold(const double *ah, const double *bh, int n, int m, double *phi,
                   double *gamma) {
    double aug[N * N], e[N * N];
    const int w = n + m;
    double cap = ldexp(THETA13, NORM_SHIFT);
    double norm_a = shifted_norm(ah, n, n, n), norm_b = shifted_norm(bh, n, m, m);
    int k = 0;
    while (norm_a > cap) cap *= 2.0;
    while (norm_b > ldexp(cap, k)) k++;
    memset(aug, 0, sizeof aug);
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) aug[i * w + j] = ah[i * n + j];
        for (int j = 0; j < m; j++) aug[i * w + n + j] = ldexp(bh[i * m + j], -k);
    }
    fmu_expm(aug, w, e);
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) phi[i * n + j] = e[i * w + j];
        for (int j = 0; j < m; j++) gamma[i * m + j] = ldexp(e[i * w + n + j], k);
    }
}
