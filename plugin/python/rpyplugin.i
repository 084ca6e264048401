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
#include "RPYMobility.h"
using OpenMM::Vec3;  // OpenMM's typemaps name it unqualified

extern "C" void registerRPYKernelFactories();

// The OpenMM version this module was compiled against (libOpenMM's C++ ABI is not stable
// across minor versions).
static const char* builtAgainstOpenMMVersion() { return KNOTMM_OPENMM_BUILD_VERSION; }

// The lower Cholesky factor of a symmetric positive definite matrix (array_like, n x n) as the
// steps compute it: choleskyLower (LAPACK when a routine is set) or, with builtin=True, the
// built-in routine. For tests; raises ValueError if the matrix is not positive definite.
static PyObject* choleskyFactor(PyObject* matrix, bool builtin) {
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
    std::vector<double> a(data, data + n * n);
    Py_DECREF(in);
    const bool ok = builtin ? KnotMM::choleskyLowerBuiltin(a, (int) n) : KnotMM::choleskyLower(a, (int) n);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "matrix: not positive definite");
        return NULL;
    }
    npy_intp dims[2] = {n, n};
    PyObject* out = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    if (out != NULL)
        std::copy(a.begin(), a.end(), (double*) PyArray_DATA((PyArrayObject*) out));
    return out;
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

// OpenMM's typemaps accept numpy arrays; they ask this first.
static bool isNumpyAvailable() { return true; }
%}

%init %{
    import_array();
%}

%import(module="openmm.openmm") "swig/OpenMMSwigHeaders.i"
%include "swig/typemaps.i"
%include <std_string.i>

// C++ exceptions become openmm.OpenMMException, as in OpenMM's own module.
%exception {
    try {
        $action
    } catch (std::exception& e) {
        PyObject* module = PyImport_ImportModule("openmm");
        PyObject* type = module ? PyObject_GetAttrString(module, "OpenMMException") : NULL;
        PyErr_Clear();
        PyErr_SetString(type ? type : PyExc_RuntimeError, e.what());
        Py_XDECREF(type);
        Py_XDECREF(module);
        SWIG_fail;
    }
}

%feature("autodoc", "0");

extern "C" void registerRPYKernelFactories();
static const char* builtAgainstOpenMMVersion();
static PyObject* choleskyFactor(PyObject* matrix, bool builtin);
static PyObject* lanczosSqrt(PyObject* positions, PyObject* z, double tolerance, double diameter,
                             double mobility);

namespace KnotMM {

void setCholeskyRoutine(unsigned long long address);
unsigned long long getCholeskyRoutine();
void setTridiagonalEigenRoutine(unsigned long long address);
unsigned long long getTridiagonalEigenRoutine();

class RPYIntegrator : public OpenMM::Integrator {
public:
    RPYIntegrator(double stepSize, const std::string& method = "rk23", double errorTolerance = 1e-4);
    const std::string& getMethod() const;
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
};

}
