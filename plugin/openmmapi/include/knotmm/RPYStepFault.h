#ifndef KNOTMM_RPY_STEP_FAULT_H_
#define KNOTMM_RPY_STEP_FAULT_H_

// A step that failed: RPYIntegrator::step and stepTo throw this (an OpenMMException, so code
// that catches those still does) with what went wrong as data, so that callers need not parse
// the message. The Python module raises knotmm.plugin.StepFault with the same fields.

#include "openmm/OpenMMException.h"

#include <limits>
#include <sstream>
#include <string>

namespace KnotMM {

/** A number in the plugin's messages: six significant digits. */
inline std::string formatNumber(double x) {
    std::ostringstream s;
    s.precision(6);
    s << x;
    return s.str();
}

class RPYStepFault : public OpenMM::OpenMMException {
public:
    enum Kind {
        NonFinite = 0,            // positions became NaN or infinite
        StepUnderflow = 1,        // error control wanted a step below the minimum step size
        NotPositiveDefinite = 2,  // the mobility could not be factorised for the noise
        LanczosNotConverged = 3,  // Lanczos noise did not reach its tolerance
    };
    /**
     * @param time           time of the last good state, in ps (NaN: not known yet)
     * @param bead           the bead concerned, or -1
     * @param errorEstimate  the error estimate over the tolerance (StepUnderflow), else NaN
     */
    RPYStepFault(Kind kind, const std::string& message, const std::string& method = "",
                 double time = std::numeric_limits<double>::quiet_NaN(), int bead = -1,
                 double errorEstimate = std::numeric_limits<double>::quiet_NaN())
        : OpenMM::OpenMMException(message), kind_(kind), method_(method), time_(time), bead_(bead),
          errorEstimate_(errorEstimate) {}
    Kind kind() const { return kind_; }
    /** "non_finite", "step_underflow", "not_positive_definite" or "lanczos_not_converged". */
    const char* kindName() const {
        static const char* const names[] = {"non_finite", "step_underflow", "not_positive_definite",
                                            "lanczos_not_converged"};
        return names[kind_];
    }
    const std::string& method() const { return method_; }
    double time() const { return time_; }
    int bead() const { return bead_; }
    double errorEstimate() const { return errorEstimate_; }
    /** The same fault, told which method's step at which time it was. */
    RPYStepFault at(const std::string& method, double time) const {
        return RPYStepFault(kind_, what(), method, time, bead_, errorEstimate_);
    }

private:
    Kind kind_;
    std::string method_;
    double time_;
    int bead_;
    double errorEstimate_;
};

} // namespace KnotMM

#endif
