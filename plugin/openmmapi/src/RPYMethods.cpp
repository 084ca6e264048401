#include "knotmm/RPYMethods.h"

#include "openmm/OpenMMException.h"

#include <algorithm>
#include <cmath>

using namespace KnotMM;

const std::vector<RPYMethodInfo>& KnotMM::rpyMethodTable() {
    static const std::vector<RPYMethodInfo> table = {
        {RPYMethod::Euler, "euler", 1, false, false},
        {RPYMethod::Heun, "heun", 2, false, false},
        {RPYMethod::Midpoint, "midpoint", 2, false, false},
        {RPYMethod::RK23, "rk23", 3, true, false},
        {RPYMethod::RKC2, "rkc2", 2, true, false},
        {RPYMethod::EulerMaruyama, "euler_maruyama", 1, false, true},
        {RPYMethod::ItoHeun, "ito_heun", 1, false, true},
        {RPYMethod::LeimkuhlerMatthews, "leimkuhler_matthews", 1, false, true},
        {RPYMethod::ItoHeunAdaptive, "ito_heun_adaptive", 1, true, true},
    };
    return table;
}

std::string KnotMM::rpyMethodNames() {
    std::string names;
    for (const RPYMethodInfo& m : rpyMethodTable())
        names += (names.empty() ? "" : ", ") + std::string(m.name);
    return names;
}

const RPYMethodInfo& KnotMM::rpyMethodInfo(const std::string& name) {
    for (const RPYMethodInfo& m : rpyMethodTable())
        if (name == m.name)
            return m;
    throw OpenMM::OpenMMException("method='" + name + "': expected one of " + rpyMethodNames());
}

const RPYMethodInfo& KnotMM::rpyMethodInfo(RPYMethod id) {
    for (const RPYMethodInfo& m : rpyMethodTable())
        if (m.id == id)
            return m;
    throw OpenMM::OpenMMException("RPYIntegrator: unknown method id " + std::to_string((int) id));
}

double KnotMM::landingSlack(double target) { return 1e-9 * std::max(1.0, std::fabs(target)); }
