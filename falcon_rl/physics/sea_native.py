"""The sea's sums over its components in native code: what the surface sampler spends its time on, written so
that a CPU compiler turns it into SIMD code.

:func:`sea_sums_wp` returns, for env i, the 14 sums of ``surface.sample_surface_wp`` over the K components of
its wave field (the equations of :mod:`falcon_rl.physics.surface`): the span-weighted elevation, the span
asymmetry and the elevation at the wing root, their gradients north and east, the elevations at both tips and
the air's flow over the waves. It is a ``wp.func_native`` snippet in plain C++.

- On the CPU the components run 8 at a time in the compiler's vector types (``vector_size(32)``: AVX on
  x86-64; no header, no intrinsic), with 8 partial sums per quantity added at the end; the count % 8 last
  components run one at a time. On CUDA every component runs one at a time (the scalar code).
- Sine and cosine: a Cody-Waite reduction (three parts of pi/2, |r| <= pi/4), the Taylor polynomials of
  sin r (to r^9) and cos r (to r^8), and the quadrant chosen by arithmetic, without branches (random phases
  would mispredict every branch). Within 2e-6 of the float64 values for |x| < 3,000 rad (a wave's phase
  ~1 km from the field's origin for its shortest components).
- The air flow's exp(-k h): a Cody-Waite reduction by ln 2, a degree-6 polynomial and the exponent built
  in the float's bits (relative error below 4e-7) on the CPU; ``expf`` on CUDA.

On the 2-core CPU this is ~4.6 ns per component on one core against ~26 ns for the same sums written in
Warp's language (``benchmarks/sea_speed.py`` has the step's figures).
"""

from __future__ import annotations

from ._warp import vector_type, wp

#: The sums of one env: (eta_bar, A, eta_root), their d/d north, their d/d east, the (right, left) tips'
#: elevations and the air's flow (north, east, up).
SEA_SUMS = 14
SeaSums = vector_type(SEA_SUMS)

_SNIPPET = r"""
    const int count = amplitude.shape.dims[1];
    const float* A = (const float*)((const char*)amplitude.data + (size_t)i * amplitude.strides[0]);
    const float* KN = (const float*)((const char*)wavenumber.data + (size_t)i * wavenumber.strides[0]);
    const float* W = (const float*)((const char*)frequency.data + (size_t)i * frequency.strides[0]);
    const float* DC = (const float*)((const char*)direction_cos.data + (size_t)i * direction_cos.strides[0]);
    const float* DS = (const float*)((const char*)direction_sin.data + (size_t)i * direction_sin.strides[0]);
    const float* PH = (const float*)((const char*)phase.data + (size_t)i * phase.strides[0]);
    // One component's (or 8 components') terms added into sums[14]: float or vector arithmetic alike.
    auto accumulate = [&](auto a, auto kn, auto w, auto dc, auto ds, auto ph, auto sincos, auto exp,
                          auto* sums) {
        decltype(a) sa, ca, sb, cb;
        sincos(kn * (north * dc + east * ds) - w * time + ph, sa, ca);
        sincos(kn * (quarter_north * dc + quarter_east * ds), sb, cb);
        const auto c2b = 2.0f * cb * cb - 1.0f;
        const auto s2b = 2.0f * sb * cb;
        const auto spread = (1.0f + 2.0f * cb + c2b) * 0.25f;
        const auto odd = (sb + s2b) * inv8b;
        sums[0] += a * ca * spread;
        sums[1] -= a * sa * odd;
        sums[2] += a * ca;
        const auto ak = -a * kn;
        const auto s0 = ak * sa * spread, s1 = ak * ca * odd, s2 = ak * sa;
        sums[3] += s0 * dc;
        sums[4] += s1 * dc;
        sums[5] += s2 * dc;
        sums[6] += s0 * ds;
        sums[7] += s1 * ds;
        sums[8] += s2 * ds;
        sums[9] += a * (ca * c2b - sa * s2b);
        sums[10] += a * (ca * c2b + sa * s2b);
        const auto flow = a * w * exp(-kn * height);
        sums[11] -= flow * ca * dc;
        sums[12] -= flow * ca * ds;
        sums[13] += flow * sa;
    };
    float acc[14];
    for (int m = 0; m < 14; ++m)
        acc[m] = 0.0f;
    int start = 0;
#if !defined(__CUDA_ARCH__)
    // 8 components at a time in the compiler's vector types (no headers, no intrinsics).
    typedef float v8f __attribute__((vector_size(32)));
    typedef int v8i __attribute__((vector_size(32)));
    typedef float v8f_unaligned __attribute__((vector_size(32), aligned(4)));
    auto load8 = [](const float* p) { return (v8f)(*(const v8f_unaligned*)p); };
    auto sincos8 = [](v8f x, v8f& s, v8f& c) {
        const v8i half = ((v8i)x & (int)0x80000000) | (int)0x3f000000;  // +-0.5 with the sign of x
        const v8i q = __builtin_convertvector(x * 0.6366197723675814f + (v8f)half, v8i);
        const v8f n = __builtin_convertvector(q, v8f);
        const v8f r = ((x - n * 1.5703125f) - n * 4.837512969970703125e-4f) - n * 7.54978995489188216e-8f;
        const v8f r2 = r * r;
        const v8f sine = r + r * r2 * (-0.16666666666666666f + r2 * (0.008333333333333333f + r2 * (
            -0.0001984126984126984f + r2 * 2.755731922398589e-06f)));
        const v8f cosine = 1.0f + r2 * (-0.5f + r2 * (0.041666666666666664f + r2 * (
            -0.001388888888888889f + r2 * 2.48015873015873e-05f)));
        const v8f odd = __builtin_convertvector(q & 1, v8f);
        const v8f sign = 1.0f - 2.0f * __builtin_convertvector((q >> 1) & 1, v8f);
        s = sign * (sine + odd * (cosine - sine));
        c = sign * (cosine - odd * (sine + cosine));
    };
    auto exp8 = [](v8f x) {  // exp(x) for x <= 0
        const v8f low = __builtin_convertvector(-(x < -87.0f), v8f);  // 1 where x < -87
        x = x + (-87.0f - x) * low;
        const v8i n = __builtin_convertvector(x * 1.4426950408889634f - 0.5f, v8i);
        const v8f fn = __builtin_convertvector(n, v8f);
        const v8f r = (x - fn * 0.693145751953125f) - fn * 1.428606765330187045e-06f;
        const v8f p = 1.0f + r * (1.0f + r * (0.5f + r * (0.16666666666666666f + r * (
            0.041666666666666664f + r * (0.008333333333333333f + r * 0.001388888888888889f)))));
        return p * (v8f)((n + 127) << 23);
    };
    v8f lanes[14];
    for (int m = 0; m < 14; ++m)
        lanes[m] = (v8f){0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    for (; start + 8 <= count; start += 8)
        accumulate(load8(A + start), load8(KN + start), load8(W + start), load8(DC + start),
                   load8(DS + start), load8(PH + start), sincos8, exp8, lanes);
    for (int m = 0; m < 14; ++m)
        for (int j = 0; j < 8; ++j)
            acc[m] += lanes[m][j];
#endif
    auto sincos1 = [](float x, float& s, float& c) {
        const int q = (int)(x * 0.6366197723675814f + (x >= 0.0f ? 0.5f : -0.5f));
        const float n = (float)q;
        const float r = ((x - n * 1.5703125f) - n * 4.837512969970703125e-4f) - n * 7.54978995489188216e-8f;
        const float r2 = r * r;
        const float sine = r + r * r2 * (-0.16666666666666666f + r2 * (0.008333333333333333f + r2 * (
            -0.0001984126984126984f + r2 * 2.755731922398589e-06f)));
        const float cosine = 1.0f + r2 * (-0.5f + r2 * (0.041666666666666664f + r2 * (
            -0.001388888888888889f + r2 * 2.48015873015873e-05f)));
        const float odd = (float)(q & 1);
        const float sign = 1.0f - 2.0f * (float)((q >> 1) & 1);
        s = sign * (sine + odd * (cosine - sine));
        c = sign * (cosine - odd * (sine + cosine));
    };
    auto exp1 = [](float x) { return expf(x); };
    for (int k = start; k < count; ++k)  // CUDA: every component; CPU: the last count % 8
        accumulate(A[k], KN[k], W[k], DC[k], DS[k], PH[k], sincos1, exp1, acc);
    wp::vec_t<14, wp::float32> out;
    for (int m = 0; m < 14; ++m)
        out.c[m] = acc[m];
    return out;
"""


@wp.func_native(_SNIPPET)
def sea_sums_wp(amplitude: wp.array2d(dtype=wp.float32), wavenumber: wp.array2d(dtype=wp.float32),
                frequency: wp.array2d(dtype=wp.float32), direction_cos: wp.array2d(dtype=wp.float32),
                direction_sin: wp.array2d(dtype=wp.float32), phase: wp.array2d(dtype=wp.float32), i: int,
                north: float, east: float, quarter_north: float, quarter_east: float, time: float,
                height: float, inv8b: float) -> SeaSums:
    """Env i's 14 sums over its components (module docstring) at the wing root (``north``, ``east``, m), with
    the quarter-span step (``quarter_north``, ``quarter_east``, m), at ``time`` s, the air's flow decaying
    from the wing's ``height`` (m, >= 0); ``inv8b`` = 1 / (8 b)."""
    ...


__all__ = ["SEA_SUMS", "SeaSums", "sea_sums_wp"]
