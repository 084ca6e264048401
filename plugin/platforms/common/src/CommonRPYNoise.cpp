// Brownian noise of CommonRPYBackend: normals made on the device (counter based), Cholesky on the
// host for small systems, Lanczos with its Krylov loop on the device.

#include "CommonRPYBackend.h"

#include "knotmm/RPYStepFault.h"
#include "knotmm/stepper/NoiseStream.h"
#include "openmm/OpenMMException.h"

#include <algorithm>
#include <cmath>

using namespace OpenMM;
using namespace KnotMM;

void CommonRPYBackend::factorNoise(const StateVector& y) {
    if (lanczos) {
        data(y).copyTo(noiseAt);  // matrix-free: applyNoise runs the Krylov iteration at noiseAt
        return;
    }
    // exact: the dense Cholesky factor of the 3n x 3n mobility, on the host
    data(y).download(host);
    factorAt(host.data());
}

void CommonRPYBackend::factorAt(const double* y) {
    noiseAtHost.resize(3 * n);
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            noiseAtHost[k * n + b] = y[3 * b + k];
    if (!cholesky.factor(hostMobility, n, noiseAtHost.data(), singleFactor))
        throw RPYStepFault(RPYStepFault::NotPositiveDefinite,
                           "RPYIntegrator: the RPY mobility is not positive definite at these "
                           "positions (two beads at the same point?)");
}

void CommonRPYBackend::applyNoise(double scale, const StateVector& z, StateVector& out) {
    if (lanczos) {
        lanczosNoise(scale, data(z), data(out));
        return;
    }
    data(z).download(host);
    hostOut.resize(3 * n);
    cholesky.times(host.data(), scale, hostOut.data());
    data(out).upload(hostOut);
}

void CommonRPYBackend::lanczosNoise(double scale, ComputeArray& z, ComputeArray& out) {
    // LanczosSqrt's iteration with the vectors on the device: per iteration the product
    // w = mu v_k, two passes of classical Gram-Schmidt against V_0..k (the first also gives
    // alpha_k = v_k . mu v_k and stands for the three-term recurrence), |w|, and one download
    // of (alpha_k, beta_k) for the small problem on the host.
    const int dim = 3 * n;
    if (!(lanczosTolerance > 0.0))
        throw OpenMMException("lanczosTolerance: must be > 0");
    const int m = std::min(dim, LANCZOS_MAX_ITER);
    if (!basis.isInitialized()) {
        basis.initialize<double>(cc, (size_t) m * dim, "rpyLanczosBasis");
        proj.initialize<double>(cc, 2 * m, "rpyLanczosProjections");  // the two Gram-Schmidt passes
        lanczosScalars.initialize<double>(cc, 2, "rpyLanczosAlphaBeta");
    }
    sumSquaresKernel->setArg(0, z);
    sumSquaresKernel->execute(reduceSize, reduceSize);
    double squares[3];
    scalars.download(squares);
    const double normZ = std::sqrt(squares[0]);
    if (normZ == 0.0) {
        cc.clearBuffer(out);
        return;
    }
    const int groups = std::max(1, std::min(m, cc.getNumThreadBlocks()));
    lanczosScaleKernel->setArg(1, basis);
    lanczosScaleKernel->setArg(4, lanczosV);
    for (ComputeKernel* k : {&lanczosDotsKernel, &lanczosSubtractKernel}) {
        (*k)->setArg(0, basis);
        (*k)->setArg(1, lanczosW);
        (*k)->setArg(2, proj);
    }
    lanczosAlphaBetaKernel->setArg(0, lanczosW);
    lanczosAlphaBetaKernel->setArg(1, proj);
    lanczosAlphaBetaKernel->setArg(3, lanczosScalars);
    auto scaleInto = [&](ComputeArray& w, int k, double c) {  // V_k = v = w / c
        lanczosScaleKernel->setArg(0, w);
        lanczosScaleKernel->setArg(2, k);
        lanczosScaleKernel->setArg(3, c);
        lanczosScaleKernel->execute(dim);
    };
    auto gramSchmidt = [&](int count, int offset) {
        // proj[offset + j] = V_j . w, then w -= sum_j proj[offset + j] V_j, for j < count
        for (ComputeKernel* k : {&lanczosDotsKernel, &lanczosSubtractKernel}) {
            (*k)->setArg(3, count);
            (*k)->setArg(4, offset);
        }
        lanczosDotsKernel->execute(groups * reduceSize, reduceSize);
        lanczosSubtractKernel->execute(dim);
    };
    scaleInto(z, 0, normZ);
    lanczosSmall.reset(m);
    int used = 0;
    double alphaBeta[2];
    for (int k = 0; k < m && used == 0; k++) {
        mobilityTimes(noiseAt, lanczosV, lanczosW);  // w = mu v_k
        gramSchmidt(k + 1, 0);                       // proj[k] = alpha_k
        gramSchmidt(k + 1, m);
        lanczosAlphaBetaKernel->setArg(2, k);
        lanczosAlphaBetaKernel->execute(reduceSize, reduceSize);
        lanczosScalars.download(alphaBeta);  // the iteration's one download
        lanczosSmall.alpha[k] = alphaBeta[0];
        lanczosSmall.beta[k] = alphaBeta[1];
        used = lanczosSmall.update(k, dim, normZ, lanczosTolerance);
        if (used == 0 && k + 1 < m)
            scaleInto(lanczosW, k + 1, lanczosSmall.beta[k]);
    }
    if (used == 0)
        lanczosSmall.notConverged(m, lanczosTolerance);
    // out = scale |z| sum_j c_j V_j
    hostOut.resize(used);
    for (int j = 0; j < used; j++)
        hostOut[j] = scale * normZ * lanczosSmall.coeff[j];
    proj.uploadSubArray(hostOut.data(), 0, used);
    lanczosCombineKernel->setArg(0, basis);
    lanczosCombineKernel->setArg(1, proj);
    lanczosCombineKernel->setArg(2, used);
    lanczosCombineKernel->setArg(3, out);
    lanczosCombineKernel->execute(dim);
}

void CommonRPYBackend::normals(NoiseStream& stream, StateVector& out) {
    if (!stream.counterBased()) {
        host.resize(3 * n);
        stream.fill(host.data(), 3 * n);
        data(out).upload(host);
        return;
    }
    counterNormalsKernel->setArg(0, data(out));
    counterNormalsKernel->setArg(1, (unsigned long long) stream.key());
    counterNormalsKernel->setArg(2, (unsigned long long) stream.takeDraw());
    counterNormalsKernel->execute((3 * n + 3) / 4);
}
