#ifndef KNOTMM_TEST_UTILITIES_H_
#define KNOTMM_TEST_UTILITIES_H_

// Small helpers shared by the plugin's C++ tests (run by ctest, see CMakeLists.txt here).
//
// Every test uses only the public API: knotmm/RPYIntegrator.h, registerRPYKernelFactories()
// and OpenMM's public headers. The expected values come from closed forms or from deliberately
// naive computations written in the tests (naiveMobilityTimes below: the RPY formula of
// shared/model.md as 3x3 blocks with explicit branches), never from the plugin itself.
//
// The checks print what they measured (name, expected, found, deviation, tolerance), so a
// ctest log (--output-on-failure, or -V) shows the margins, and throw on failure; main()
// catches, prints and returns 1.

#include "OpenMM.h"
#include "knotmm/RPYIntegrator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

extern "C" void registerRPYKernelFactories();

namespace knotmm_test {

/** A failed check: the message says what, where, and by how much. */
struct Failure : std::runtime_error {
    explicit Failure(const std::string& what) : std::runtime_error(what) {}
};

inline std::string where(const char* file, int line) {
    std::ostringstream s;
    s << file << ":" << line;
    return s.str();
}

/** Plain assertion. */
#define KT_ASSERT(cond)                                                                       \
    do {                                                                                      \
        if (!(cond))                                                                          \
            throw knotmm_test::Failure(knotmm_test::where(__FILE__, __LINE__) + ": " #cond); \
    } while (0)

/**
 * |found - expected| <= tol (absolute). Prints the deviation whether or not it passes (quiet =
 * false), so the log carries the measured margins.
 */
inline double checkAbs(const std::string& name, double expected, double found, double tol,
                       const std::string& at, bool quiet = false) {
    const double dev = std::fabs(found - expected);
    if (!quiet)
        std::printf("  %-58s expected %.15g found %.15g |dev| %.3g (tol %.3g)\n", name.c_str(),
                    expected, found, dev, tol);
    if (!(dev <= tol)) {
        std::ostringstream s;
        s.precision(17);
        s << at << ": " << name << ": expected " << expected << ", found " << found
          << ", |deviation| " << dev << " > tolerance " << tol;
        throw Failure(s.str());
    }
    return dev;
}

/** |found - expected| <= tol * max(|expected|, 1e-300) (relative). */
inline double checkRel(const std::string& name, double expected, double found, double tol,
                       const std::string& at, bool quiet = false) {
    const double dev = std::fabs(found - expected) / std::max(std::fabs(expected), 1e-300);
    if (!quiet)
        std::printf("  %-58s expected %.15g found %.15g rel dev %.3g (tol %.3g)\n", name.c_str(),
                    expected, found, dev, tol);
    if (!(dev <= tol)) {
        std::ostringstream s;
        s.precision(17);
        s << at << ": " << name << ": expected " << expected << ", found " << found
          << ", relative deviation " << dev << " > tolerance " << tol;
        throw Failure(s.str());
    }
    return dev;
}

#define KT_CHECK_ABS(name, expected, found, tol) \
    knotmm_test::checkAbs(name, expected, found, tol, knotmm_test::where(__FILE__, __LINE__))
#define KT_CHECK_REL(name, expected, found, tol) \
    knotmm_test::checkRel(name, expected, found, tol, knotmm_test::where(__FILE__, __LINE__))

/** fn() must throw OpenMM::OpenMMException; prints its message. */
inline void expectOpenMMException(const std::string& name, const std::function<void()>& fn,
                                  const std::string& at) {
    try {
        fn();
    }
    catch (const OpenMM::OpenMMException& e) {
        std::printf("  %-40s raised OpenMMException: %s\n", name.c_str(), e.what());
        return;
    }
    throw Failure(at + ": " + name + ": expected an OpenMMException, none was raised");
}

#define KT_EXPECT_THROW(name, fn) \
    knotmm_test::expectOpenMMException(name, fn, knotmm_test::where(__FILE__, __LINE__))

/**
 * Registers the RPY kernels; first loads OpenMM's CPU and OpenCL platform plugins from the
 * wheel's plugin directory (KNOTMM_TEST_OPENMM_PLUGIN_DIR, set by CMake), so that the kernel
 * is registered for CPU too (CPU must exist before registerRPYKernelFactories() runs), then
 * the plugin's OpenCL library (KNOTMM_TEST_OPENCL_LIBRARY, when CMake built it), whose
 * registerKernelFactories() OpenMM calls. Returns whether the CPU platform is available.
 * Idempotent; openclStatus() says whether OpenCL can be tested.
 */
inline std::string& openclSkipReason() {
    static std::string reason = "not set up";
    return reason;
}

inline bool havePlatform(const std::string& name) {
    for (int i = 0; i < OpenMM::Platform::getNumPlatforms(); i++)
        if (OpenMM::Platform::getPlatform(i).getName() == name)
            return true;
    return false;
}

inline bool setUpPlatforms() {
    static int cpu = -1;
    if (cpu >= 0)
        return cpu == 1;
    cpu = 0;
#ifdef KNOTMM_TEST_OPENMM_PLUGIN_DIR
    for (const char* name : {"CPU", "OpenCL"}) {
        if (havePlatform(name))
            continue;
        try {
            OpenMM::Platform::loadPluginLibrary(std::string(KNOTMM_TEST_OPENMM_PLUGIN_DIR) + "/libOpenMM" + name + ".so");
        }
        catch (const std::exception& e) {
            std::printf("  (%s platform not loaded: %s)\n", name, e.what());
        }
    }
#endif
    cpu = havePlatform("CPU") ? 1 : 0;
    registerRPYKernelFactories();
    openclSkipReason() = "";
#ifdef KNOTMM_TEST_OPENCL_LIBRARY
    if (!havePlatform("OpenCL"))
        openclSkipReason() = "OpenMM has no OpenCL platform here";
    else {
        try {
            OpenMM::Platform::loadPluginLibrary(KNOTMM_TEST_OPENCL_LIBRARY);
            OpenMM::Platform& platform = OpenMM::Platform::getPlatformByName("OpenCL");
            if (!platform.supportsKernels({"IntegrateRPYStep"}))
                openclSkipReason() = "the plugin's OpenCL library registered no kernel";
            else {
                // a device must be there: a one-particle Context with a Verlet integrator
                OpenMM::System system;
                system.addParticle(1.0);
                OpenMM::VerletIntegrator verlet(0.001);
                OpenMM::Context context(system, verlet, platform, {{"Precision", "double"}});
            }
        }
        catch (const std::exception& e) {
            openclSkipReason() = e.what();
        }
    }
#else
    openclSkipReason() = "the plugin's OpenCL library was not built (KNOTMM_OPENCL=OFF, or no CL/cl.h or "
                         "libOpenMMOpenCL.so at configure time)";
#endif
    if (!openclSkipReason().empty())
        std::printf("  (OpenCL not tested: %s)\n", openclSkipReason().c_str());
    return cpu == 1;
}

/**
 * The platforms to run on: Reference always, CPU when it loaded, and OpenCL in double and in
 * mixed precision ("OpenCL:double", "OpenCL:mixed") when its library loaded and it has a
 * device (pocl on the build machine; each OpenCL Context costs ~0.1 s there). With
 * `bothPrecisions` false, OpenCL in mixed precision only (what knotmm runs; for tests whose
 * subject does not depend on the precision).
 */
inline std::vector<std::string> platformNames(bool bothPrecisions = true) {
    std::vector<std::string> names = {"Reference"};
    if (setUpPlatforms())
        names.push_back("CPU");
    if (openclSkipReason().empty()) {
        if (bothPrecisions)
            names.push_back("OpenCL:double");
        names.push_back("OpenCL:mixed");
    }
    return names;
}

/** True for a device platform (OpenCL, CUDA, HIP): forces in fixed point, kernels with fast math. */
inline bool isDevice(const std::string& platformName) {
    return platformName.compare(0, 6, "OpenCL") == 0 || platformName.compare(0, 4, "CUDA") == 0 ||
           platformName.compare(0, 3, "HIP") == 0;
}

/**
 * A tolerance for the platform: `host` on Reference and CPU, `device` on a device platform,
 * whose forces reach the integrator as 64-bit fixed point (2^-32 ~ 2.3e-10 resolution) and
 * whose kernels are compiled with FMA contraction: it agrees with the host to rounding, not
 * bit for bit.
 */
inline double tolerance(const std::string& platformName, double host, double device) {
    return isDevice(platformName) ? device : host;
}

/**
 * A Context on the named platform (CPU: one thread, so results do not depend on the machine;
 * "OpenCL:<precision>": the OpenCL platform in that precision).
 */
inline OpenMM::Context* makeContext(OpenMM::System& system, OpenMM::Integrator& integrator,
                                    const std::string& platformName) {
    setUpPlatforms();
    const size_t colon = platformName.find(':');
    const std::string name = platformName.substr(0, colon);
    OpenMM::Platform& platform = OpenMM::Platform::getPlatformByName(name);
    if (name == "CPU")
        return new OpenMM::Context(system, integrator, platform, {{"Threads", "1"}});
    if (colon != std::string::npos)
        return new OpenMM::Context(system, integrator, platform, {{"Precision", platformName.substr(colon + 1)}});
    return new OpenMM::Context(system, integrator, platform);
}

inline std::vector<OpenMM::Vec3> positionsOf(OpenMM::Context& context) {
    return context.getState(OpenMM::State::Positions).getPositions();
}

/**
 * The naive RPY block mu_ij / mu0 for the separation rv = r_j - r_i of two beads of diameter d,
 * written straight from shared/model.md with an explicit branch (the plugin uses a branch-free
 * vectorised form with unnormalised rvec; this is the textbook one with rhat):
 *   r >= d: 3d/(8r) [ (1 + d^2/(6 r^2)) I + (1 - d^2/(2 r^2)) rhat rhat ]
 *   r <  d: (1 - 9r/(16d)) I + (3r/(16d)) rhat rhat
 *   i = j : I
 */
inline void rpyBlock(const OpenMM::Vec3& rv, double d, double m[3][3]) {
    const double r = std::sqrt(rv.dot(rv));
    double a, b;
    if (r == 0.0) {
        a = 1.0;
        b = 0.0;
    }
    else if (r >= d) {
        a = 3.0 * d / (8.0 * r) * (1.0 + d * d / (6.0 * r * r));
        b = 3.0 * d / (8.0 * r) * (1.0 - d * d / (2.0 * r * r));
    }
    else {
        a = 1.0 - 9.0 * r / (16.0 * d);
        b = 3.0 * r / (16.0 * d);
    }
    const double rhat[3] = {r > 0 ? rv[0] / r : 0.0, r > 0 ? rv[1] / r : 0.0, r > 0 ? rv[2] / r : 0.0};
    for (int k = 0; k < 3; k++)
        for (int l = 0; l < 3; l++)
            m[k][l] = (k == l ? a : 0.0) + b * rhat[k] * rhat[l];
}

/** v_i = sum_j mu_ij F_j with naive 3x3 blocks (O(N^2), one bead pair at a time). */
inline std::vector<OpenMM::Vec3> naiveMobilityTimes(const std::vector<OpenMM::Vec3>& x,
                                                    const std::vector<OpenMM::Vec3>& f, double d,
                                                    double mu0) {
    std::vector<OpenMM::Vec3> v(x.size());
    for (size_t i = 0; i < x.size(); i++) {
        OpenMM::Vec3 sum;
        for (size_t j = 0; j < x.size(); j++) {
            double m[3][3];
            rpyBlock(x[j] - x[i], d, m);
            for (int k = 0; k < 3; k++)
                sum[k] += m[k][0] * f[j][0] + m[k][1] * f[j][1] + m[k][2] * f[j][2];
        }
        v[i] = sum * mu0;
    }
    return v;
}

/**
 * Runs a test body: prints the test's name, catches failures and OpenMM errors, returns the
 * process exit status (0 passed, 1 failed).
 */
inline int runTest(const char* name, const std::function<void()>& body) {
    std::printf("%s\n", name);
    try {
        body();
    }
    catch (const std::exception& e) {
        std::printf("FAILED: %s\n", e.what());
        return 1;
    }
    std::printf("Done\n");
    return 0;
}

} // namespace knotmm_test

#endif
