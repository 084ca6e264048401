// Device kernels of CommonRPYBackend, in OpenMM's common kernel language (KERNEL, GLOBAL,
// LOCAL, GLOBAL_ID, ...: compiled by ComputeContext::compileProgram for OpenCL, CUDA or HIP).
//
// Defined by the backend when it compiles this file:
//   NUM_BEADS         beads (the System's particles that are not virtual sites)
//   NUM_ATOMS         particles in the Context's arrays (posq, the force buffer)
//   PADDED_NUM_ATOMS  the force buffer's stride between x, y and z
//   TILE              work-group size of the pair loop (mobilityTimes)
//   REDUCE_SIZE       work-group size of the one-group reductions (a power of two)
// and by the platform: real4, USE_MIXED_PRECISION (posq float4 + a float4 correction).
//
// Vectors are 3 NUM_BEADS doubles, bead-major (x0, y0, z0, x1, ...). Context arrays are in
// the Context's atom order: entry i holds particle atomIndex[i]; particleBead maps a
// particle to its bead, or -1 for a virtual site.

/** True when x is an infinity or a NaN, by its exponent bits (safe under fast-math flags). */
inline DEVICE bool notFinite(double x) {
    union {
        double d;
        mm_long l;
    } u;
    u.d = x;
    return ((u.l >> 52) & 0x7ff) == 0x7ff;
}

/** y = the beads' positions in posq (+ posqCorrection in mixed precision). */
KERNEL void readPositions(GLOBAL const real4* RESTRICT posq,
#ifdef USE_MIXED_PRECISION
        GLOBAL const real4* RESTRICT posqCorrection,
#endif
        GLOBAL const int* RESTRICT atomIndex, GLOBAL const int* RESTRICT particleBead, GLOBAL double* RESTRICT y) {
    for (int i = GLOBAL_ID; i < NUM_ATOMS; i += GLOBAL_SIZE) {
        const int b = particleBead[atomIndex[i]];
        if (b < 0)
            continue;
        const real4 p = posq[i];
#ifdef USE_MIXED_PRECISION
        const real4 c = posqCorrection[i];
        y[3*b] = (double) p.x + (double) c.x;
        y[3*b+1] = (double) p.y + (double) c.y;
        y[3*b+2] = (double) p.z + (double) c.z;
#else
        y[3*b] = p.x;
        y[3*b+1] = p.y;
        y[3*b+2] = p.z;
#endif
    }
}

/**
 * p with its x, y, z = (px, py, pz) as the Context stores positions (its w, the charge, kept);
 * *c = the float of the remainders (mixed precision splits each number as OpenMM does).
 */
inline DEVICE real4 roundedPosition(real4 p, double px, double py, double pz, real4* c) {
    p.x = (real) px;
    p.y = (real) py;
    p.z = (real) pz;
    *c = make_real4((real) (px - (double) p.x), (real) (py - (double) p.y), (real) (pz - (double) p.z), 0);
    return p;
}

/**
 * posq (+ posqCorrection) of the beads = y - shift (shift: 3 doubles, the centre of mass or
 * zeros); the charge (w) is kept. Mixed precision splits each number as OpenMM does: a float
 * and the float of the remainder.
 */
KERNEL void writePositions(GLOBAL real4* RESTRICT posq,
#ifdef USE_MIXED_PRECISION
        GLOBAL real4* RESTRICT posqCorrection,
#endif
        GLOBAL const int* RESTRICT atomIndex, GLOBAL const int* RESTRICT particleBead, GLOBAL const double* RESTRICT y,
        GLOBAL const double* RESTRICT shift) {
    const double sx = shift[0], sy = shift[1], sz = shift[2];
    for (int i = GLOBAL_ID; i < NUM_ATOMS; i += GLOBAL_SIZE) {
        const int b = particleBead[atomIndex[i]];
        if (b < 0)
            continue;
        const double px = y[3*b] - sx, py = y[3*b+1] - sy, pz = y[3*b+2] - sz;
        real4 c;
        posq[i] = roundedPosition(posq[i], px, py, pz, &c);
#ifdef USE_MIXED_PRECISION
        posqCorrection[i] = c;
#endif
    }
}

/**
 * part[0], part[REDUCE_SIZE], part[2 REDUCE_SIZE] = the sums of the beads' x, y and z, seen by
 * every work item of the one work group of REDUCE_SIZE that calls it (3 REDUCE_SIZE doubles).
 */
DEVICE void sumPositions(GLOBAL const double* RESTRICT y, LOCAL_ARG double* part) {
    double sx = 0, sy = 0, sz = 0;
    for (int b = LOCAL_ID; b < NUM_BEADS; b += LOCAL_SIZE) {
        sx += y[3*b];
        sy += y[3*b+1];
        sz += y[3*b+2];
    }
    part[LOCAL_ID] = sx;
    part[REDUCE_SIZE+LOCAL_ID] = sy;
    part[2*REDUCE_SIZE+LOCAL_ID] = sz;
    for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
        SYNC_THREADS;
        if (LOCAL_ID < stride) {
            part[LOCAL_ID] += part[LOCAL_ID+stride];
            part[REDUCE_SIZE+LOCAL_ID] += part[REDUCE_SIZE+LOCAL_ID+stride];
            part[2*REDUCE_SIZE+LOCAL_ID] += part[2*REDUCE_SIZE+LOCAL_ID+stride];
        }
    }
    SYNC_THREADS;
}

/** com = the mean of the beads' positions (one work group of REDUCE_SIZE). */
KERNEL void centreOfMass(GLOBAL const double* RESTRICT y, GLOBAL double* RESTRICT com) {
    LOCAL double part[3*REDUCE_SIZE];
    sumPositions(y, part);
    if (LOCAL_ID == 0) {
        com[0] = part[0]/NUM_BEADS;
        com[1] = part[REDUCE_SIZE]/NUM_BEADS;
        com[2] = part[2*REDUCE_SIZE]/NUM_BEADS;
    }
}

/** f = the beads' forces from the 64-bit fixed-point force buffer (scale 2^-32). */
KERNEL void readForces(GLOBAL const mm_long* RESTRICT force, GLOBAL const int* RESTRICT atomIndex,
        GLOBAL const int* RESTRICT particleBead, GLOBAL double* RESTRICT f) {
    const double scale = 1.0/4294967296.0;
    for (int i = GLOBAL_ID; i < NUM_ATOMS; i += GLOBAL_SIZE) {
        const int b = particleBead[atomIndex[i]];
        if (b < 0)
            continue;
        f[3*b] = scale*(double) force[i];
        f[3*b+1] = scale*(double) force[i+PADDED_NUM_ATOMS];
        f[3*b+2] = scale*(double) force[i+2*PADDED_NUM_ATOMS];
    }
}

/**
 * v = mu(x) f with the overlap-corrected RPY mobility of beads of diameter d (mu0 the single
 * bead's mobility): mu_ij / mu0 = a I + b rvec rvec^T for rvec = x_j - x_i, r = |rvec|,
 *   r >= d: a = 3d/(8r) (1 + d^2/(6r^2)),  b = 3d/(8r) (1 - d^2/(2r^2)) / r^2,
 *   r <  d: a = 1 - 9r/(16d),              b = 3/(16 d r),
 *   r = 0 (the bead itself): a = 1, b = 0.
 * The rows base .. base + TILE - 1, one work item per bead i summing over all j; the beads j
 * come through local memory (`tile`, 6 TILE doubles) in tiles of TILE (the work-group size).
 * Every work item of the group runs the same loops (a bead past the end computes bead
 * NUM_BEADS-1 again and writes nothing): no divergence around the barriers. The sum of a row
 * does not depend on which group computes it (mobilityTimes and mobilityCopies agree).
 */
DEVICE void mobilityRows(GLOBAL const double* RESTRICT x, GLOBAL const double* RESTRICT f, GLOBAL double* v,
        int base, double d, double mu0, LOCAL_ARG double* tile) {
    const double invD = 1.0/d;
    const int i = base+LOCAL_ID;
    const int row = (i < NUM_BEADS ? i : NUM_BEADS-1);
    const double xi = x[3*row], yi = x[3*row+1], zi = x[3*row+2];
    double ax = 0, ay = 0, az = 0;
    for (int start = 0; start < NUM_BEADS; start += TILE) {
        SYNC_THREADS;
        const int j = start+LOCAL_ID;
        if (j < NUM_BEADS) {
            tile[6*LOCAL_ID] = x[3*j];
            tile[6*LOCAL_ID+1] = x[3*j+1];
            tile[6*LOCAL_ID+2] = x[3*j+2];
            tile[6*LOCAL_ID+3] = f[3*j];
            tile[6*LOCAL_ID+4] = f[3*j+1];
            tile[6*LOCAL_ID+5] = f[3*j+2];
        }
        SYNC_THREADS;
        const int count = (NUM_BEADS-start < TILE ? NUM_BEADS-start : TILE);
        for (int k = 0; k < count; k++) {
            const double r0 = tile[6*k]-xi, r1 = tile[6*k+1]-yi, r2 = tile[6*k+2]-zi;
            const double fx = tile[6*k+3], fy = tile[6*k+4], fz = tile[6*k+5];
            const double rr = r0*r0+r1*r1+r2*r2;
            double a = 1, b = 0;
            if (rr > 0) {
                const double inv = 1.0/sqrt(rr);
                const double r = rr*inv;
                if (r >= d) {
                    const double s = d*inv, s2 = s*s;
                    a = 0.375*s*(1.0+s2/6.0);
                    b = 0.375*s*(1.0-0.5*s2)*(inv*inv);
                }
                else {
                    a = 1.0-0.5625*r*invD;
                    b = 0.1875*inv*invD;
                }
            }
            const double rf = b*(r0*fx+r1*fy+r2*fz);
            ax += a*fx+rf*r0;
            ay += a*fy+rf*r1;
            az += a*fz+rf*r2;
        }
    }
    if (i < NUM_BEADS) {
        v[3*i] = mu0*ax;
        v[3*i+1] = mu0*ay;
        v[3*i+2] = mu0*az;
    }
}

/** v = mu(x) f (mobilityRows), the groups taking the tiles of rows in turn. */
KERNEL void mobilityTimes(GLOBAL const double* RESTRICT x, GLOBAL const double* RESTRICT f, GLOBAL double* RESTRICT v,
        double d, double mu0) {
    LOCAL double tile[6*TILE];
    for (int base = GROUP_ID*TILE; base < NUM_BEADS; base += NUM_GROUPS*TILE)
        mobilityRows(x, f, v, base, d, mu0, tile);
}

/** result[0] = sum of v_i^2 (one work group of REDUCE_SIZE). */
KERNEL void sumSquares(GLOBAL const double* RESTRICT v, GLOBAL double* RESTRICT result) {
    LOCAL double part[REDUCE_SIZE];
    double s = 0;
    for (int i = LOCAL_ID; i < 3*NUM_BEADS; i += LOCAL_SIZE)
        s += v[i]*v[i];
    part[LOCAL_ID] = s;
    for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
        SYNC_THREADS;
        if (LOCAL_ID < stride)
            part[LOCAL_ID] += part[LOCAL_ID+stride];
    }
    SYNC_THREADS;
    if (LOCAL_ID == 0)
        result[0] = part[0];
}

/** result[0] = the smallest index i with v_i not finite, or 3 NUM_BEADS (one work group). */
KERNEL void firstNonFinite(GLOBAL const double* RESTRICT v, GLOBAL int* RESTRICT result) {
    LOCAL int first[REDUCE_SIZE];
    int found = 3*NUM_BEADS;
    for (int i = LOCAL_ID; i < 3*NUM_BEADS; i += LOCAL_SIZE)
        if (notFinite(v[i]) && i < found)
            found = i;
    first[LOCAL_ID] = found;
    for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
        SYNC_THREADS;
        if (LOCAL_ID < stride && first[LOCAL_ID+stride] < first[LOCAL_ID])
            first[LOCAL_ID] = first[LOCAL_ID+stride];
    }
    SYNC_THREADS;
    if (LOCAL_ID == 0)
        result[0] = first[0];
}

/**
 * result[0] = the number of i with a_i != b_i, both taken as the Context stores positions:
 * in mixed precision a float and the float of the remainder, in single precision a float (so
 * a vector and its round trip through posq count as equal); in double precision the numbers
 * themselves.
 */
KERNEL void countDifferent(GLOBAL const double* RESTRICT a, GLOBAL const double* RESTRICT b, GLOBAL int* RESTRICT result) {
    LOCAL int count[REDUCE_SIZE];
    int c = 0;
    for (int i = LOCAL_ID; i < 3*NUM_BEADS; i += LOCAL_SIZE) {
#ifdef USE_MIXED_PRECISION
        const float ha = (float) a[i], hb = (float) b[i];
        const float la = (float) (a[i]-(double) ha), lb = (float) (b[i]-(double) hb);
        if (ha != hb || la != lb)
            c++;
#elif defined(KNOTMM_SINGLE)
        if ((float) a[i] != (float) b[i])
            c++;
#else
        if (a[i] != b[i])
            c++;
#endif
    }
    count[LOCAL_ID] = c;
    for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
        SYNC_THREADS;
        if (LOCAL_ID < stride)
            count[LOCAL_ID] += count[LOCAL_ID+stride];
    }
    SYNC_THREADS;
    if (LOCAL_ID == 0)
        result[0] = count[0];
}

/**
 * The reductions of checkTry, in one work group of REDUCE_SIZE (every work item reads them):
 * worst[0] = max over beads of |err_b|^2, bad[0] = the number of beads for which it is not
 * finite (none when err is null), first[0] = the smallest index i with y1_i not finite, or
 * 3 NUM_BEADS.
 */
DEVICE void checkTryParts(GLOBAL const double* RESTRICT err, GLOBAL const double* RESTRICT y1,
        LOCAL_ARG double* worst, LOCAL_ARG double* bad, LOCAL_ARG int* first) {
    double w = 0, nb = 0;
    if (err != 0)
        for (int b = LOCAL_ID; b < NUM_BEADS; b += LOCAL_SIZE) {
            const double s = err[3*b]*err[3*b]+err[3*b+1]*err[3*b+1]+err[3*b+2]*err[3*b+2];
            if (notFinite(s))
                nb += 1;
            else
                w = (s > w ? s : w);
        }
    int found = 3*NUM_BEADS;
    for (int i = LOCAL_ID; i < 3*NUM_BEADS; i += LOCAL_SIZE)
        if (notFinite(y1[i]) && i < found)
            found = i;
    worst[LOCAL_ID] = w;
    bad[LOCAL_ID] = nb;
    first[LOCAL_ID] = found;
    for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
        SYNC_THREADS;
        if (LOCAL_ID < stride) {
            worst[LOCAL_ID] = (worst[LOCAL_ID+stride] > worst[LOCAL_ID] ? worst[LOCAL_ID+stride] : worst[LOCAL_ID]);
            bad[LOCAL_ID] += bad[LOCAL_ID+stride];
            if (first[LOCAL_ID+stride] < first[LOCAL_ID])
                first[LOCAL_ID] = first[LOCAL_ID+stride];
        }
    }
    SYNC_THREADS;
}

/**
 * What the end of a try needs, in one download (one work group of REDUCE_SIZE):
 * result[0] = max over beads of |err_b|^2, result[1] = the number of beads for which it is
 * not finite, result[2] = the smallest index i with y1_i not finite, or 3 NUM_BEADS
 * (firstNonFinite). With err = y1 = v, result[0] and [1] are maxBeadNorm's.
 */
KERNEL void checkTry(GLOBAL const double* RESTRICT err, GLOBAL const double* RESTRICT y1, GLOBAL double* RESTRICT result) {
    LOCAL double worst[REDUCE_SIZE];
    LOCAL double bad[REDUCE_SIZE];
    LOCAL int first[REDUCE_SIZE];
    checkTryParts(err, y1, worst, bad, first);
    if (LOCAL_ID == 0) {
        result[0] = worst[0];
        result[1] = bad[0];
        result[2] = first[0];
    }
}

// --- Lanczos noise (CommonRPYNoise.cpp): the Krylov vectors on the device --------------------
// The basis V holds the Krylov vectors one after another, DIM = 3 NUM_BEADS numbers each.

/** proj[offset+j] = V_j . w for j < count (one work group of REDUCE_SIZE per j). */
KERNEL void lanczosDots(GLOBAL const double* RESTRICT basis, GLOBAL const double* RESTRICT w,
        GLOBAL double* RESTRICT proj, int count, int offset) {
    LOCAL double part[REDUCE_SIZE];
    for (int j = GROUP_ID; j < count; j += NUM_GROUPS) {
        GLOBAL const double* v = basis+(mm_long) j*(3*NUM_BEADS);
        double s = 0;
        for (int i = LOCAL_ID; i < 3*NUM_BEADS; i += LOCAL_SIZE)
            s += v[i]*w[i];
        part[LOCAL_ID] = s;
        for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
            SYNC_THREADS;
            if (LOCAL_ID < stride)
                part[LOCAL_ID] += part[LOCAL_ID+stride];
        }
        SYNC_THREADS;
        if (LOCAL_ID == 0)
            proj[offset+j] = part[0];
        SYNC_THREADS;
    }
}

/** w -= sum_j proj[offset+j] V_j over j < count (the sum in the order of j). */
KERNEL void lanczosSubtract(GLOBAL const double* RESTRICT basis, GLOBAL double* RESTRICT w,
        GLOBAL const double* RESTRICT proj, int count, int offset) {
    for (int i = GLOBAL_ID; i < 3*NUM_BEADS; i += GLOBAL_SIZE) {
        double s = 0;
        for (int j = 0; j < count; j++)
            s += proj[offset+j]*basis[(mm_long) j*(3*NUM_BEADS)+i];
        w[i] -= s;
    }
}

/**
 * result[0] = proj[k] (alpha_k, from the first Gram-Schmidt pass), result[1] = |w| (beta_k):
 * the one download of an iteration (one work group of REDUCE_SIZE).
 */
KERNEL void lanczosAlphaBeta(GLOBAL const double* RESTRICT w, GLOBAL const double* RESTRICT proj, int k,
        GLOBAL double* RESTRICT result) {
    LOCAL double part[REDUCE_SIZE];
    double s = 0;
    for (int i = LOCAL_ID; i < 3*NUM_BEADS; i += LOCAL_SIZE)
        s += w[i]*w[i];
    part[LOCAL_ID] = s;
    for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
        SYNC_THREADS;
        if (LOCAL_ID < stride)
            part[LOCAL_ID] += part[LOCAL_ID+stride];
    }
    SYNC_THREADS;
    if (LOCAL_ID == 0) {
        result[0] = proj[k];
        result[1] = sqrt(part[0]);
    }
}

/** V_k = v = w / c (c: |z| for the first vector, beta_(k-1) after; v: the product's input). */
KERNEL void lanczosScale(GLOBAL const double* RESTRICT w, GLOBAL double* RESTRICT basis, int k, double c,
        GLOBAL double* RESTRICT v) {
    GLOBAL double* vk = basis+(mm_long) k*(3*NUM_BEADS);
    for (int i = GLOBAL_ID; i < 3*NUM_BEADS; i += GLOBAL_SIZE) {
        const double x = w[i]/c;
        vk[i] = x;
        v[i] = x;
    }
}

/** out = sum_j coeff[j] V_j over j < count. */
KERNEL void lanczosCombine(GLOBAL const double* RESTRICT basis, GLOBAL const double* RESTRICT coeff, int count,
        GLOBAL double* RESTRICT out) {
    for (int i = GLOBAL_ID; i < 3*NUM_BEADS; i += GLOBAL_SIZE) {
        double s = 0;
        for (int j = 0; j < count; j++)
            s += coeff[j]*basis[(mm_long) j*(3*NUM_BEADS)+i];
        out[i] = s;
    }
}

// --- counter-based normals (the stepper's Philox.h, the same integer operations) -----------

/** hi and lo words of a * b from 32-bit halves. */
inline DEVICE void philoxMulHiLo(mm_ulong a, mm_ulong b, mm_ulong* hi, mm_ulong* lo) {
    const mm_ulong aLo = a & 0xffffffffUL, aHi = a >> 32, bLo = b & 0xffffffffUL, bHi = b >> 32;
    const mm_ulong ll = aLo * bLo, lh = aLo * bHi, hl = aHi * bLo, hh = aHi * bHi;
    const mm_ulong middle = (ll >> 32) + (lh & 0xffffffffUL) + (hl & 0xffffffffUL);
    *lo = (middle << 32) | (ll & 0xffffffffUL);
    *hi = hh + (lh >> 32) + (hl >> 32) + (middle >> 32);
}

/** z_even, z_odd by Box-Muller from two words (Philox.h: boxMuller). */
inline DEVICE void philoxBoxMuller(mm_ulong wRadius, mm_ulong wAngle, double* z0, double* z1) {
    const double u = ((double) (wRadius >> 11) + 1.0) * 1.1102230246251565e-16;
    const double v = (double) (wAngle >> 11) * 1.1102230246251565e-16;
    const double r = sqrt(-2.0 * log(u));
    const double angle = 6.283185307179586 * v;
    *z0 = r * cos(angle);
    *z1 = r * sin(angle);
}

/**
 * out[4b .. 4b+3] (those below 3 NUM_BEADS) = normals 4b..4b+3 of draw `draw` under `key`:
 * Philox4x64-10 of the counter (b, draw, 0, 0) under the key (key, 0).
 */
DEVICE void philoxNormalsBlock(GLOBAL double* RESTRICT out, mm_ulong key, mm_ulong draw, int b) {
    mm_ulong c0 = (mm_ulong) b, c1 = draw, c2 = 0, c3 = 0, k0 = key, k1 = 0;
    for (int round = 0; round < 10; round++) {
        if (round > 0) {
            k0 += 0x9E3779B97F4A7C15UL;
            k1 += 0xBB67AE8584CAA73BUL;
        }
        mm_ulong hi0, lo0, hi1, lo1;
        philoxMulHiLo(0xD2E7470EE14C6C93UL, c0, &hi0, &lo0);
        philoxMulHiLo(0xCA5A826395121157UL, c2, &hi1, &lo1);
        c0 = hi1 ^ c1 ^ k0;
        c1 = lo1;
        c2 = hi0 ^ c3 ^ k1;
        c3 = lo0;
    }
    double z[4];
    philoxBoxMuller(c0, c1, &z[0], &z[1]);
    philoxBoxMuller(c2, c3, &z[2], &z[3]);
    for (int j = 0; j < 4 && 4 * b + j < 3 * NUM_BEADS; j++)
        out[4 * b + j] = z[j];
}

/** out = the 3 NUM_BEADS normals of draw `draw` under `key` (philoxNormalsBlock). One thread a block. */
KERNEL void counterNormals(GLOBAL double* RESTRICT out, mm_ulong key, mm_ulong draw) {
    for (int b = GLOBAL_ID; 4 * b < 3 * NUM_BEADS; b += GLOBAL_SIZE)
        philoxNormalsBlock(out, key, draw, b);
}

// --- K copies of n beads in one Context (CommonRPYBatch; NUM_BEADS is n) ----------------------
// `all` holds every copy's 3n numbers one after another (copy j's beads are the System's beads
// j n .. (j + 1) n - 1); `centres` 4 doubles per copy: its centre of mass and its reach (the
// largest distance of a bead from that centre). The batch reads the Context with readPositions
// and readForces under a particleBead over all copies' beads.

/** to[toOffset + i] = from[fromOffset + i] for i < count. */
KERNEL void moveNumbers(GLOBAL const double* RESTRICT from, int fromOffset, GLOBAL double* RESTRICT to, int toOffset,
        int count) {
    for (int i = GLOBAL_ID; i < count; i += GLOBAL_SIZE)
        to[toOffset+i] = from[fromOffset+i];
}

// A batch keeps every copy's vectors in one array, the arena (3n numbers a vector, at an
// offset of its own); `table` holds what the host packed for a round (offsets as doubles,
// exact below 2^53). The per-copy kernels below take the copies listed at table[base ..] in
// turn, one work group (or one tile of rows) per copy, so one launch serves every copy.

/**
 * For listed copy c (its y at arena + table[base + c]): all[c] = y, centres[4c ..] = its centre
 * of mass (summed as centreOfMass sums, so a copy is shifted exactly as when it is alone) and
 * its reach (the largest distance of a bead from that centre). Work groups of REDUCE_SIZE.
 */
KERNEL void gatherCopies(GLOBAL const double* RESTRICT arena, GLOBAL const double* RESTRICT table, int base,
        int copies, GLOBAL double* RESTRICT all, GLOBAL double* RESTRICT centres) {
    LOCAL double part[3*REDUCE_SIZE];
    for (int copy = GROUP_ID; copy < copies; copy += NUM_GROUPS) {
        SYNC_THREADS;
        GLOBAL const double* RESTRICT y = arena+(int) table[base+copy];
        sumPositions(y, part);  // as centreOfMass sums
        const double cx = part[0]/NUM_BEADS, cy = part[REDUCE_SIZE]/NUM_BEADS, cz = part[2*REDUCE_SIZE]/NUM_BEADS;
        SYNC_THREADS;
        GLOBAL double* RESTRICT out = all+3*(mm_long) copy*NUM_BEADS;
        double reach = 0;
        for (int b = LOCAL_ID; b < NUM_BEADS; b += LOCAL_SIZE) {
            const double x = y[3*b], yy = y[3*b+1], z = y[3*b+2];
            out[3*b] = x;
            out[3*b+1] = yy;
            out[3*b+2] = z;
            const double rr = (x-cx)*(x-cx)+(yy-cy)*(yy-cy)+(z-cz)*(z-cz);
            reach = (rr > reach ? rr : reach);  // a NaN is left out: such a copy fails on its own
        }
        part[LOCAL_ID] = reach;
        for (int stride = REDUCE_SIZE/2; stride > 0; stride /= 2) {
            SYNC_THREADS;
            if (LOCAL_ID < stride && part[LOCAL_ID+stride] > part[LOCAL_ID])
                part[LOCAL_ID] = part[LOCAL_ID+stride];
        }
        SYNC_THREADS;
        if (LOCAL_ID == 0) {
            centres[4*copy] = cx;
            centres[4*copy+1] = cy;
            centres[4*copy+2] = cz;
            centres[4*copy+3] = sqrt(part[0]);
        }
    }
}

/**
 * posq (+ posqCorrection) of every copy's beads = (all - its centre) + its grid point: copy j
 * at ((j % side - m) s, ((j / side) % side - m) s, (j / side^2 - m) s), m = (side - 1) / 2, s =
 * spacing (0: every copy at its own centre of mass). Rounded as writePositions rounds.
 */
KERNEL void writeCopies(GLOBAL real4* RESTRICT posq,
#ifdef USE_MIXED_PRECISION
        GLOBAL real4* RESTRICT posqCorrection,
#endif
        GLOBAL const int* RESTRICT atomIndex, GLOBAL const int* RESTRICT particleBead, GLOBAL const double* RESTRICT all,
        GLOBAL const double* RESTRICT centres, double spacing, int side) {
    const double middle = 0.5*(side-1);
    for (int i = GLOBAL_ID; i < NUM_ATOMS; i += GLOBAL_SIZE) {
        const int g = particleBead[atomIndex[i]];
        if (g < 0)
            continue;
        const int j = g/NUM_BEADS;
        const double ox = ((double) (j%side)-middle)*spacing, oy = ((double) ((j/side)%side)-middle)*spacing,
                oz = ((double) (j/(side*side))-middle)*spacing;
        const double px = (all[3*g]-centres[4*j])+ox, py = (all[3*g+1]-centres[4*j+1])+oy,
                pz = (all[3*g+2]-centres[4*j+2])+oz;
        real4 c;
        posq[i] = roundedPosition(posq[i], px, py, pz, &c);
#ifdef USE_MIXED_PRECISION
        posqCorrection[i] = c;
#endif
    }
}

/**
 * For listed copy c, table[base + 3c ..] = (x, copy, v): arena[v ..] = mu(arena[x ..]) f, f
 * the copy's forces (forces + 3n copy). One tile of TILE rows (mobilityRows) a work group.
 */
KERNEL void mobilityCopies(GLOBAL double* arena, GLOBAL const double* RESTRICT forces,
        GLOBAL const double* RESTRICT table, int base, int copies, double d, double mu0) {
    LOCAL double tile[6*TILE];
    const int tiles = (NUM_BEADS+TILE-1)/TILE;
    for (int unit = GROUP_ID; unit < copies*tiles; unit += NUM_GROUPS) {
        GLOBAL const double* entry = table+base+3*(unit/tiles);
        mobilityRows(arena+(int) entry[0], forces+3*(mm_long) ((int) entry[1])*NUM_BEADS, arena+(int) entry[2],
                     (unit%tiles)*TILE, d, mu0, tile);
    }
}

/**
 * checkTry for listed copy c, table[base + 2c ..] = (err, y1) offsets (err < 0: none, its
 * norm 0): result[3c ..] as checkTry's result. One work group of REDUCE_SIZE a copy.
 */
KERNEL void checkCopies(GLOBAL const double* RESTRICT arena, GLOBAL const double* RESTRICT table, int base,
        int copies, GLOBAL double* RESTRICT result) {
    LOCAL double worst[REDUCE_SIZE];
    LOCAL double bad[REDUCE_SIZE];
    LOCAL int first[REDUCE_SIZE];
    for (int copy = GROUP_ID; copy < copies; copy += NUM_GROUPS) {
        SYNC_THREADS;
        const int errAt = (int) table[base+2*copy];
        checkTryParts(errAt < 0 ? 0 : arena+errAt, arena+(int) table[base+2*copy+1], worst, bad, first);
        if (LOCAL_ID == 0) {
            result[3*copy] = worst[0];
            result[3*copy+1] = bad[0];
            result[3*copy+2] = first[0];
        }
    }
}

/**
 * counterNormals for listed copy c, table[base + 5c ..] = (out offset, key low and high 32
 * bits, draw low and high 32 bits). One thread a block of four normals.
 */
KERNEL void normalsCopies(GLOBAL double* arena, GLOBAL const double* RESTRICT table, int base, int copies) {
    const int blocks = (3*NUM_BEADS+3)/4;
    for (int g = GLOBAL_ID; g < copies*blocks; g += GLOBAL_SIZE) {
        GLOBAL const double* e = table+base+5*(g/blocks);
        const mm_ulong key = (mm_ulong) e[1] | ((mm_ulong) e[2] << 32);
        const mm_ulong draw = (mm_ulong) e[3] | ((mm_ulong) e[4] << 32);
        philoxNormalsBlock(arena+(int) e[0], key, draw, g%blocks);
    }
}

/** bulk[3n e ..] = arena[table[base + e] ..] for entry e < count (3n numbers each). */
KERNEL void collectVectors(GLOBAL const double* RESTRICT arena, GLOBAL const double* RESTRICT table, int base,
        int count, GLOBAL double* RESTRICT bulk) {
    for (int g = GLOBAL_ID; g < count*3*NUM_BEADS; g += GLOBAL_SIZE) {
        const int e = g/(3*NUM_BEADS);
        bulk[g] = arena[(int) table[base+e]+g-e*3*NUM_BEADS];
    }
}

/** arena[table[base + e] ..] = bulk[3n e ..] for entry e < count (3n numbers each). */
KERNEL void spreadVectors(GLOBAL const double* RESTRICT bulk, GLOBAL const double* RESTRICT table, int base,
        int count, GLOBAL double* RESTRICT arena) {
    for (int g = GLOBAL_ID; g < count*3*NUM_BEADS; g += GLOBAL_SIZE) {
        const int e = g/(3*NUM_BEADS);
        arena[(int) table[base+e]+g-e*3*NUM_BEADS] = bulk[g];
    }
}
