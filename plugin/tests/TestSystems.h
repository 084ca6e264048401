#ifndef KNOTMM_TEST_SYSTEMS_H_
#define KNOTMM_TEST_SYSTEMS_H_

// Small systems and comparisons shared by the device tests (TestRPYDevice.cpp,
// TestRPYOutsideChanges.cpp): a perturbed ring or open chain with bonds, bending and gravity
// whose parameters are rounded to float (OpenMM's device platforms keep them in float), and the
// largest difference of two sets of positions.

#include "OpenMM.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace knotmm_test {

typedef std::vector<OpenMM::Vec3> Vecs;
const double PI = 3.14159265358979323846;

/**
 * x rounded to single precision. Through a volatile: GCC 12.2 at -O2 drops a plain (float) cast
 * in `v.push_back(Vec3((float) a, (float) b, c))` inside a loop (seen while writing this test).
 */
inline double singleRounded(double x) {
    volatile float f = (float) x;
    return f;
}

inline double maxDeviation(const Vecs& a, const Vecs& b, const OpenMM::Vec3& offset = OpenMM::Vec3()) {
    double worst = 0.0;
    for (size_t i = 0; i < a.size(); i++)
        for (int k = 0; k < 3; k++)
            worst = std::max(worst, std::fabs(a[i][k] - offset[k] - b[i][k]));
    return worst;
}

/**
 * A ring of n beads (an open chain with `open`), bonds 0.6, bending and gravity in force groups
 * 0, 1, 2, its start perturbed from a circle around (offset, -offset, offset).
 */
inline OpenMM::System* ringSystem(int n, Vecs& start, double offset = 0.0, bool open = false) {
    using namespace OpenMM;
    System* system = new System();
    HarmonicBondForce* bonds = new HarmonicBondForce();
    HarmonicAngleForce* angles = new HarmonicAngleForce();
    CustomExternalForce* gravity = new CustomExternalForce("g*z");
    gravity->addGlobalParameter("g", 1.0);
    const double radius = 0.6 / (2.0 * std::sin(PI / n));
    for (int i = 0; i < n; i++) {
        system->addParticle(1.0);
        gravity->addParticle(i, {});
        const double a = 2.0 * PI * i / n;
        const double r = radius * (1.0 + 0.05 * std::cos(3 * a));
        start.push_back(Vec3(offset + r * std::cos(a), -offset + r * std::sin(a), offset + 0.3 * std::cos(2 * a)));
    }
    // OpenMM's device platforms keep bonded parameters in single precision: give both platforms
    // the same numbers (0.6 and pi rounded to float)
    const int bondCount = open ? n - 1 : n;
    for (int i = 0; i < bondCount; i++)
        bonds->addBond(i, (i + 1) % n, singleRounded(0.6), 50.0);
    for (int i = 0; i < (open ? n - 2 : n); i++)
        angles->addAngle(i, (i + 1) % n, (i + 2) % n, singleRounded(PI), 2.0);
    bonds->setForceGroup(0);
    angles->setForceGroup(1);
    gravity->setForceGroup(2);
    system->addForce(bonds);
    system->addForce(angles);
    system->addForce(gravity);
    return system;
}

} // namespace knotmm_test

#endif
