// SWIG interface of the knotmm RPY plugin. Importing OpenMM's own interface makes the Python
// class RPYIntegrator a subclass of openmm.Integrator, so Context and app.Simulation accept it.
%module(package="knotmm.plugin") rpyplugin

%{
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include "OpenMM.h"
#include "OpenMMAmoeba.h"
#include "OpenMMDrude.h"
#include "openmm/RPMDIntegrator.h"
#include "openmm/RPMDMonteCarloBarostat.h"
#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYMethods.h"
#include "knotmm/RPYStepFault.h"
#include "RPYMobility.h"
#include "knotmm/stepper/Philox.h"
using OpenMM::Vec3;  // OpenMM's typemaps name it unqualified

extern "C" void registerRPYKernelFactories();

// The OpenMM version this module was compiled against (libOpenMM's C++ ABI is not stable
// across minor versions).
static const char* builtAgainstOpenMMVersion() { return KNOTMM_OPENMM_BUILD_VERSION; }

// The lower Cholesky factor of a symmetric positive definite matrix (array_like, n x n), as
// `factorise` makes it in the Real of its vector, returned as a double array. For the tests'
// helpers below; raises ValueError if the matrix is not square or not positive definite.
template <class Real, class Factorise>
static PyObject* factorOf(PyObject* matrix, Factorise factorise) {
    PyArrayObject* in = (PyArrayObject*) PyArray_FROMANY(matrix, NPY_DOUBLE, 2, 2, NPY_ARRAY_CARRAY_RO);
    if (in == NULL)
        return NULL;
    const npy_intp n = PyArray_DIM(in, 0);
    if (PyArray_DIM(in, 1) != n) {
        Py_DECREF(in);
        PyErr_SetString(PyExc_ValueError, "matrix: expected a square array");
        return NULL;
    }
    const double* data = (const double*) PyArray_DATA(in);
    std::vector<Real> a(data, data + n * n);
    Py_DECREF(in);
    if (!factorise(a, (int) n)) {
        PyErr_SetString(PyExc_ValueError, "matrix: not positive definite");
        return NULL;
    }
    npy_intp dims[2] = {n, n};
    PyObject* out = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    if (out != NULL)
        std::copy(a.begin(), a.end(), (double*) PyArray_DATA((PyArrayObject*) out));
    return out;
}

// The factor as the steps compute it: choleskyLower (LAPACK when a routine is set) or, with
// builtin=True, the built-in routine. For tests.
static PyObject* choleskyFactor(PyObject* matrix, bool builtin) {
    return factorOf<double>(matrix, [builtin](std::vector<double>& a, int n) {
        return builtin ? KnotMM::choleskyLowerBuiltin(a, n) : KnotMM::choleskyLower(a, n);
    });
}

// The factor in single precision as the steps compute it with a noise precision of "single"
// (the matrix rounded to float, then spotrf when handed over). For tests.
static PyObject* singleCholeskyFactor(PyObject* matrix) {
    return factorOf<float>(matrix, [](std::vector<float>& a, int n) { return KnotMM::choleskyLower(a, n); });
}

// mu(x)^(1/2) z by the steps' Lanczos routine (LanczosSqrt): positions (n, 3) and z (3n
// numbers, bead-major) array_like, in d and mu0 units given by diameter and mobility (LAPACK's
// dstev must have been handed over). Returns the tuple (y as an array of shape (n, 3),
// iterations). For tests.
static PyObject* lanczosSqrt(PyObject* positions, PyObject* z, double tolerance, double diameter,
                             double mobility) {
    PyArrayObject* px = (PyArrayObject*) PyArray_FROMANY(positions, NPY_DOUBLE, 2, 2, NPY_ARRAY_CARRAY_RO);
    if (px == NULL)
        return NULL;
    PyArrayObject* pz = (PyArrayObject*) PyArray_FROMANY(z, NPY_DOUBLE, 1, 2, NPY_ARRAY_CARRAY_RO);
    if (pz == NULL) {
        Py_DECREF(px);
        return NULL;
    }
    const npy_intp n = PyArray_DIM(px, 0);
    if (PyArray_DIM(px, 1) != 3 || PyArray_SIZE(pz) != 3 * n) {
        Py_DECREF(px);
        Py_DECREF(pz);
        PyErr_SetString(PyExc_ValueError, "positions: expected shape (n, 3); z: 3n numbers");
        return NULL;
    }
    const double* x = (const double*) PyArray_DATA(px);
    const double* zz = (const double*) PyArray_DATA(pz);
    std::vector<double> xs(3 * n), zs(3 * n), ys(3 * n);
    for (npy_intp b = 0; b < n; b++)
        for (int k = 0; k < 3; k++) {
            xs[k * n + b] = x[3 * b + k];
            zs[k * n + b] = zz[3 * b + k];
        }
    Py_DECREF(px);
    Py_DECREF(pz);
    KnotMM::RPYMobility mob(diameter, mobility, 1);
    KnotMM::LanczosSqrt solver;
    const int iterations = solver.compute(mob, (int) n, xs.data(), zs.data(), tolerance, ys.data());
    npy_intp dims[2] = {n, 3};
    PyObject* out = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    if (out == NULL)
        return NULL;
    double* y = (double*) PyArray_DATA((PyArrayObject*) out);
    for (npy_intp b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            y[3 * b + k] = ys[k * n + b];
    return Py_BuildValue("(Ni)", out, iterations);
}

// The method table (RPYMethods.h) as a tuple of (name, order, adaptive, stochastic).
static PyObject* methodTable() {
    const std::vector<KnotMM::RPYMethodInfo>& table = KnotMM::rpyMethodTable();
    PyObject* out = PyTuple_New((Py_ssize_t) table.size());
    for (size_t i = 0; i < table.size(); i++)
        PyTuple_SET_ITEM(out, (Py_ssize_t) i,
                         Py_BuildValue("(siNN)", table[i].name, table[i].order, PyBool_FromLong(table[i].adaptive),
                                       PyBool_FromLong(table[i].stochastic)));
    return out;
}

static double landingSlack(double target) { return KnotMM::landingSlack(target); }

// The `count` normals of draw `draw` of a run seeded with `seed` (its noise stream's key), as the
// stepper makes them on every platform (stepper/Philox.h). A numpy array; for tests.
static PyObject* counterNormals(unsigned long long seed, unsigned long long draw, int count) {
    if (count < 0) {
        PyErr_SetString(PyExc_ValueError, "count: expected a number >= 0");
        return NULL;
    }
    npy_intp dims[1] = {count};
    PyObject* out = PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    if (out != NULL)
        KnotMM::philox::normals(seed, draw, (double*) PyArray_DATA((PyArrayObject*) out), count);
    return out;
}

// Raise knotmm.plugin.rpyplugin.StepFault (defined in this module's Python part) for a fault;
// falls back to openmm.OpenMMException if that class cannot be found.
static void raiseStepFault(const KnotMM::RPYStepFault& fault) {
    PyObject* module = PyImport_ImportModule("knotmm.plugin.rpyplugin");
    PyObject* type = module ? PyObject_GetAttrString(module, "StepFault") : NULL;
    PyObject* value = type ? PyObject_CallFunction(type, "sssdid", fault.what(), fault.kindName(),
                                                   fault.method().c_str(), fault.time(), fault.bead(),
                                                   fault.errorEstimate()) : NULL;
    if (value != NULL) {
        PyErr_SetObject(type, value);
        Py_DECREF(value);
    }
    else {
        PyErr_Clear();
        PyObject* openmm = PyImport_ImportModule("openmm");
        PyObject* base = openmm ? PyObject_GetAttrString(openmm, "OpenMMException") : NULL;
        PyErr_Clear();
        PyErr_SetString(base ? base : PyExc_RuntimeError, fault.what());
        Py_XDECREF(base);
        Py_XDECREF(openmm);
    }
    Py_XDECREF(type);
    Py_XDECREF(module);
}

// Raise openmm.OpenMMException (RuntimeError if it cannot be found) with a C++ exception's text.
static void raiseOpenMMException(const char* what) {
    PyObject* module = PyImport_ImportModule("openmm");
    PyObject* type = module ? PyObject_GetAttrString(module, "OpenMMException") : NULL;
    PyErr_Clear();
    PyErr_SetString(type ? type : PyExc_RuntimeError, what);
    Py_XDECREF(type);
    Py_XDECREF(module);
}

// OpenMM's typemaps accept numpy arrays; they ask this first.
static bool isNumpyAvailable() { return true; }
%}

%init %{
    import_array();
%}

%import(module="openmm.openmm") "swig/OpenMMSwigHeaders.i"
%include "swig/typemaps.i"
%include <std_string.i>

// A failed step becomes knotmm.plugin.rpyplugin.StepFault (an openmm.OpenMMException with the
// fault's fields); other C++ exceptions become openmm.OpenMMException, as in OpenMM's module.
%exception {
    try {
        $action
    } catch (KnotMM::RPYStepFault& fault) {
        raiseStepFault(fault);
        SWIG_fail;
    } catch (std::exception& e) {
        raiseOpenMMException(e.what());
        SWIG_fail;
    }
}

// The steps (of one system, and of a replica set's copies) run without Python's global
// interpreter lock, as OpenMM's own Integrator.step does: runs in other threads of the
// process (a replica set's, knotmm.engine.copies) step at the same time. The integrator calls no Python while it steps (LAPACK's routines are C
// function pointers taken beforehand).
%define KNOTMM_STEP_WITHOUT_GIL(name)
%exception KnotMM::RPYIntegrator::name {
    PyThreadState* threadState = PyEval_SaveThread();
    try {
        $action
    } catch (KnotMM::RPYStepFault& fault) {
        PyEval_RestoreThread(threadState);
        raiseStepFault(fault);
        SWIG_fail;
    } catch (std::exception& e) {
        PyEval_RestoreThread(threadState);
        raiseOpenMMException(e.what());
        SWIG_fail;
    }
    PyEval_RestoreThread(threadState);
}
%enddef
KNOTMM_STEP_WITHOUT_GIL(step)
KNOTMM_STEP_WITHOUT_GIL(stepTo)
KNOTMM_STEP_WITHOUT_GIL(stepToWithin)
KNOTMM_STEP_WITHOUT_GIL(stepCopiesTo)

%feature("autodoc", "0");

%pythoncode %{
import openmm as _openmm_module


class StepFault(_openmm_module.OpenMMException):
    """A step of :class:`RPYIntegrator` failed; the Context keeps the last good state.

    Attributes
    ----------
    kind : str
        ``"non_finite"`` (positions became NaN or infinite), ``"step_underflow"`` (error
        control wanted a step below the minimum step size), ``"not_positive_definite"`` (the
        mobility could not be factorised for the noise) or ``"lanczos_not_converged"``.
    method : str
        The integration method.
    time : float
        Time of the last good state, in ps (= tau_d).
    bead : int
        The bead concerned (``non_finite``: the first non-finite one), or -1.
    error_estimate : float
        ``step_underflow``: the error estimate over the tolerance; else nan.
    """

    def __init__(self, message, kind="", method="", time=float("nan"), bead=-1,
                 error_estimate=float("nan")):
        super().__init__(message)
        self.kind = kind
        self.method = method
        self.time = time
        self.bead = bead
        self.error_estimate = error_estimate

    def __reduce__(self):
        return (type(self), (str(self), self.kind, self.method, self.time, self.bead,
                             self.error_estimate))
%}

extern "C" void registerRPYKernelFactories();
static const char* builtAgainstOpenMMVersion();
static PyObject* methodTable();
static double landingSlack(double target);
static PyObject* counterNormals(unsigned long long seed, unsigned long long draw, int count);
static PyObject* choleskyFactor(PyObject* matrix, bool builtin);
static PyObject* singleCholeskyFactor(PyObject* matrix);
static PyObject* lanczosSqrt(PyObject* positions, PyObject* z, double tolerance, double diameter,
                             double mobility);

namespace KnotMM {

void setCholeskyRoutine(unsigned long long address);
unsigned long long getCholeskyRoutine();
void setSingleCholeskyRoutine(unsigned long long address);
unsigned long long getSingleCholeskyRoutine();
void setTridiagonalEigenRoutine(unsigned long long address);
unsigned long long getTridiagonalEigenRoutine();

class RPYIntegrator : public OpenMM::Integrator {
public:
    RPYIntegrator(double stepSize, const std::string& method = "rk23", double errorTolerance = 1e-4);
    const std::string& getMethod() const;
    void setMethod(const std::string& name);
    bool isAdaptive() const;
    bool isStochastic() const;
    double getErrorTolerance() const;
    void setErrorTolerance(double tol);
    double getBeadDiameter() const;
    void setBeadDiameter(double d);
    double getMobility() const;
    void setMobility(double mu0);
    double getThermalEnergy() const;
    void setThermalEnergy(double kT);
    const std::string& getNoiseMethod() const;
    void setNoiseMethod(const std::string& method);
    double getLanczosTolerance() const;
    void setLanczosTolerance(double tol);
    const std::string& getNoisePrecision() const;
    void setNoisePrecision(const std::string& precision);
    int getRandomNumberSeed() const;
    void setRandomNumberSeed(int seed);
    double getMinimumStepSize() const;
    void setMinimumStepSize(double h);
    double getMaximumStepSize() const;
    void setMaximumStepSize(double h);
    int getNumThreads() const;
    void setNumThreads(int n);
    void setSpectralRadiusStartVector(const std::vector<Vec3>& v);
    virtual void step(int steps);
    void stepTo(double time);
    bool stepToWithin(double time, double maxSeconds);
    long long getNumForceEvaluations() const;
%extend {
    // groups: a sequence of ints (0..31); returns a tuple of floats, kJ/mol, one per group.
    PyObject* getGroupEnergies(PyObject* groups) {
        PyObject* seq = PySequence_Fast(groups, "groups: expected a sequence of force groups (ints 0..31)");
        if (seq == NULL)
            return NULL;
        std::vector<int> wanted;
        const Py_ssize_t count = PySequence_Fast_GET_SIZE(seq);
        for (Py_ssize_t i = 0; i < count; i++) {
            long g = PyLong_AsLong(PySequence_Fast_GET_ITEM(seq, i));
            if (g == -1 && PyErr_Occurred()) {
                Py_DECREF(seq);
                PyErr_SetString(PyExc_TypeError, "groups: expected a sequence of force groups (ints 0..31)");
                return NULL;
            }
            wanted.push_back((int) g);
        }
        Py_DECREF(seq);
        const std::vector<double> energies = $self->getGroupEnergies(wanted);
        PyObject* out = PyTuple_New((Py_ssize_t) energies.size());
        for (size_t i = 0; i < energies.size(); i++)
            PyTuple_SET_ITEM(out, (Py_ssize_t) i, PyFloat_FromDouble(energies[i]));
        return out;
    }
}
    long long getNumAcceptedSteps() const;
    long long getNumRejectedSteps() const;
    int getLastStages() const;
    double getSpectralRadius() const;
    double estimateSpectralRadius();
    void setNumCopies(int copies);
    int getNumCopies() const;
    void setCopiesApart(bool apart);
    bool getCopiesApart() const;
    bool stepCopiesTo(const std::vector<double>& targets, double maxSeconds);
    std::vector<double> getCopyPositions(int copy) const;
    void setCopyPositions(int copy, const std::vector<double>& positions);
    double getCopyTime(int copy) const;
    void setCopyTime(int copy, double time);
    std::string getCopyFaultKind(int copy) const;
    std::string getCopyFaultMessage(int copy) const;
    void clearCopyFault(int copy);
    double getCopySpacing() const;
%extend {
    // The integrator's state (step size, stepper) and a copy's, as bytes; restored from bytes.
    PyObject* getIntegratorState() const {
        const std::string state = $self->getIntegratorState();
        return PyBytes_FromStringAndSize(state.data(), (Py_ssize_t) state.size());
    }
    void setIntegratorState(PyObject* state) {
        char* buffer = NULL;
        Py_ssize_t size = 0;
        if (PyBytes_AsStringAndSize(state, &buffer, &size) != 0)
            throw OpenMM::OpenMMException("setIntegratorState: expected bytes");
        $self->setIntegratorState(std::string(buffer, (size_t) size));
    }
    PyObject* getCopyState(int copy) const {
        const std::string state = $self->getCopyState(copy);
        return PyBytes_FromStringAndSize(state.data(), (Py_ssize_t) state.size());
    }
    void setCopyState(int copy, PyObject* state) {
        char* buffer = NULL;
        Py_ssize_t size = 0;
        if (PyBytes_AsStringAndSize(state, &buffer, &size) != 0)
            throw OpenMM::OpenMMException("setCopyState: expected bytes");
        $self->setCopyState(copy, std::string(buffer, (size_t) size));
    }
}
%extend {
    // As OpenMM's plugins: the RPYIntegrator behind a base-class reference (what
    // XmlSerializer and CompoundIntegrator hand back), and whether there is one.
    static KnotMM::RPYIntegrator& cast(OpenMM::Integrator& integrator) {
        return dynamic_cast<KnotMM::RPYIntegrator&>(integrator);
    }
    static bool isinstance(OpenMM::Integrator& integrator) {
        return dynamic_cast<KnotMM::RPYIntegrator*>(&integrator) != NULL;
    }
}
};

}

%pythoncode %{
#: The Python class that casts give: ``knotmm.plugin`` sets it to its own subclass of
#: :class:`RPYIntegrator` (same C++ object, keyword arguments and a short repr).
cast_class = None


def _as_rpy(integrator):
    """``integrator`` as an :class:`RPYIntegrator` when it is one in C++, taking over ownership."""
    if isinstance(integrator, RPYIntegrator) or not isinstance(integrator, _openmm_module.Integrator):
        return integrator
    if not RPYIntegrator.isinstance(integrator):
        return integrator
    cast = RPYIntegrator.cast(integrator)
    if cast_class is not None:
        cast.__class__ = cast_class
    if integrator.thisown:  # the new proxy owns the C++ object; the old one no longer does
        integrator.thisown = False
        cast.thisown = True
    return cast


def _install_casts():
    """Make ``openmm.XmlSerializer.deserialize`` and ``clone`` give back RPYIntegrators.

    OpenMM's own module casts the integrators it knows; a plugin's class is cast here, once,
    when this module is imported (``knotmm.plugin`` imports it).
    """
    serializer = _openmm_module.XmlSerializer
    for name in ("_deserializeIntegrator", "_cloneIntegrator"):
        original = getattr(serializer, name, None)
        if original is None or getattr(original, "_knotmm_cast", False):
            continue

        def wrapped(arg, _original=original):
            return _as_rpy(_original(arg))

        wrapped._knotmm_cast = True
        wrapped.__doc__ = original.__doc__
        setattr(serializer, name, staticmethod(wrapped))


_install_casts()
%}
