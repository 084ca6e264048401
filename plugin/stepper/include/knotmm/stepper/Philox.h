#ifndef KNOTMM_STEPPER_PHILOX_H_
#define KNOTMM_STEPPER_PHILOX_H_

// The counter-based normals of the stepper's noise: Philox4x64-10 (Salmon, Moraes, Dror and
// Shaw, SC'11: ten rounds of two 64 x 64 -> 128-bit products, the key bumped by Weyl constants)
// turned into normals by Box-Muller. Normal j of draw d under key k is a pure function of
// (k, d, j): no state but the draw counter, the same on every platform. The device kernels
// (platforms/common/kernels/rpy.cc) do the same integer operations in OpenMM's kernel language;
// tests/plugin/test_plugin_counter_noise.py holds both to numpy's Philox and to Box-Muller
// written out in the test.
//
// Layout: block b of draw d is Philox4x64-10 of the counter (b, d, 0, 0) under the key (k, 0);
// its four 64-bit words w0..w3 give normals 4b..4b+3 as (w0, w1) and (w2, w3) pairs:
//   r = sqrt(-2 ln u),  u = ((w_even >> 11) + 1) 2^-53 in (0, 1]
//   z_even = r cos(2 pi v),  z_odd = r sin(2 pi v),  v = (w_odd >> 11) 2^-53 in [0, 1)

#include <cmath>
#include <cstdint>

namespace KnotMM {
namespace philox {

/** hi and lo words of a * b, from 32-bit halves (the device kernels do the same). */
inline void mulHiLo(uint64_t a, uint64_t b, uint64_t& hi, uint64_t& lo) {
    const uint64_t aLo = a & 0xffffffffULL, aHi = a >> 32, bLo = b & 0xffffffffULL, bHi = b >> 32;
    const uint64_t ll = aLo * bLo, lh = aLo * bHi, hl = aHi * bLo, hh = aHi * bHi;
    const uint64_t middle = (ll >> 32) + (lh & 0xffffffffULL) + (hl & 0xffffffffULL);
    lo = (middle << 32) | (ll & 0xffffffffULL);
    hi = hh + (lh >> 32) + (hl >> 32) + (middle >> 32);
}

/** out = Philox4x64-10(counter, key). */
inline void block(const uint64_t counter[4], const uint64_t key[2], uint64_t out[4]) {
    uint64_t c0 = counter[0], c1 = counter[1], c2 = counter[2], c3 = counter[3];
    uint64_t k0 = key[0], k1 = key[1];
    for (int round = 0; round < 10; round++) {
        if (round > 0) {
            k0 += 0x9E3779B97F4A7C15ULL;
            k1 += 0xBB67AE8584CAA73BULL;
        }
        uint64_t hi0, lo0, hi1, lo1;
        mulHiLo(0xD2E7470EE14C6C93ULL, c0, hi0, lo0);
        mulHiLo(0xCA5A826395121157ULL, c2, hi1, lo1);
        c0 = hi1 ^ c1 ^ k0;
        c1 = lo1;
        c2 = hi0 ^ c3 ^ k1;
        c3 = lo0;
    }
    out[0] = c0;
    out[1] = c1;
    out[2] = c2;
    out[3] = c3;
}

/** Two normals from two words by Box-Muller (see the layout above). */
inline void boxMuller(uint64_t wRadius, uint64_t wAngle, double& z0, double& z1) {
    const double u = ((double) (wRadius >> 11) + 1.0) * 0x1.0p-53;
    const double v = (double) (wAngle >> 11) * 0x1.0p-53;
    const double r = std::sqrt(-2.0 * std::log(u));
    const double angle = 6.283185307179586 * v;
    z0 = r * std::cos(angle);
    z1 = r * std::sin(angle);
}

/** out[0..count) = normals 0..count-1 of draw `draw` under `key`. */
inline void normals(uint64_t key, uint64_t draw, double* out, int count) {
    const uint64_t k[2] = {key, 0};
    for (int b = 0; 4 * b < count; b++) {
        const uint64_t counter[4] = {(uint64_t) b, draw, 0, 0};
        uint64_t w[4];
        block(counter, k, w);
        double z[4];
        boxMuller(w[0], w[1], z[0], z[1]);
        boxMuller(w[2], w[3], z[2], z[3]);
        for (int j = 0; j < 4 && 4 * b + j < count; j++)
            out[4 * b + j] = z[j];
    }
}

} // namespace philox
} // namespace KnotMM

#endif
