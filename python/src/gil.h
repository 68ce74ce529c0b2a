/* SPDX-License-Identifier: BSD-3-Clause */
// The GIL around the library's calls and callbacks, and a thread that the interpreter ends.
//
// A thread that takes the GIL while the interpreter exits (a daemon thread still solving when
// the main thread ends) never gets it: CPython ends the thread with pthread_exit, a forced
// unwind (abi::__forced_unwind) that starts inside the GIL acquisition, even inside the
// Python code of a callback. The thread state it unwinds is already freed and the GIL belongs
// to the exiting main thread, so on its way out the unwind must not touch the interpreter:
// no GIL taken or given back (pybind11's scoped GIL guards do both in their destructors, and
// one more pthread_exit from a destructor is std::terminate), and no reference count changed
// (an object freed without the GIL corrupts the allocator the main thread is still using).
// Hence these helpers instead of the guards, PyRef instead of py::object for what our frames
// own while Python code may run, and py::handle (borrowed) for what the caller's frame holds.
#ifndef PYSBA_GIL_H
#define PYSBA_GIL_H

#include <pybind11/pybind11.h>

#include <initializer_list>
#include <utility>

#if defined(__GLIBCXX__)
#include <cxxabi.h>
#define PYSBA_FORCED_UNWIND_PASSES_THROUGH \
  catch (abi::__forced_unwind &) {         \
    throw;                                 \
  }
#else
#define PYSBA_FORCED_UNWIND_PASSES_THROUGH
#endif

namespace pysba {

namespace py = pybind11;

// An owned reference that is given back only by a thread that holds the GIL: one that is
// being ended without it leaks the object instead (see above).
class PyRef {
 public:
  PyRef() = default;
  // Takes over a new reference (null allowed).
  explicit PyRef(PyObject *owned) : p_(owned) {}
  explicit PyRef(py::object &&o) : p_(o.release().ptr()) {}
  PyRef(PyRef &&o) noexcept : p_(std::exchange(o.p_, nullptr)) {}
  PyRef &operator=(PyRef &&o) noexcept {
    std::swap(p_, o.p_);
    return *this;
  }
  ~PyRef() {
    if (p_ && PyGILState_Check()) Py_DECREF(p_);
  }
  PyObject *get() const { return p_; }
  py::handle handle() const { return p_; }
  explicit operator bool() const { return p_ != nullptr; }
  // A py::object with a reference of its own, for the Python side (GIL held).
  py::object object() const { return py::reinterpret_borrow<py::object>(p_); }

 private:
  PyObject *p_ = nullptr;
};

// fn(args...) (the GIL held): the result, or py::error_already_set. Called through the C API
// so that no pybind11 temporary holds a reference while the callee's Python code runs.
inline PyRef call_python(py::handle fn, std::initializer_list<py::handle> args) {
  PyRef tuple(PyTuple_New(Py_ssize_t(args.size())));
  if (!tuple) throw py::error_already_set();
  Py_ssize_t k = 0;
  for (py::handle a : args) PyTuple_SET_ITEM(tuple.get(), k++, a.inc_ref().ptr());
  PyRef r(PyObject_Call(fn.ptr(), tuple.get(), nullptr));
  if (!r) throw py::error_already_set();
  return r;
}

// body() with the GIL released (the library's work); `released` holds this thread's state
// meanwhile, for with_gil. A forced unwind from inside leaves without taking the GIL back:
// taking it would only end the thread again.
template <class Body>
auto without_gil(PyThreadState *&released, Body body) {
  released = PyEval_SaveThread();
  try {
    auto r = body();
    PyEval_RestoreThread(released);
    released = nullptr;
    return r;
  }
  PYSBA_FORCED_UNWIND_PASSES_THROUGH
  catch (...) {
    PyEval_RestoreThread(released);
    released = nullptr;
    throw;
  }
}

template <class Body>
auto without_gil(Body body) {
  PyThreadState *released = nullptr;
  return without_gil(released, body);
}

// body() with the GIL, in a callback of the library on the thread that released it in
// without_gil. It takes back that thread's own state, as Py_END_ALLOW_THREADS does: the
// PyGILState functions look the state up in the interpreter, which at exit may already have
// forgotten it and then makes a new one in a finalized interpreter. body must handle its own
// exceptions; only a forced unwind leaves it, and then without the GIL given back.
template <class Body>
void with_gil(PyThreadState *&released, Body body) {
  PyEval_RestoreThread(released);
  body();
  released = PyEval_SaveThread();
}

}  // namespace pysba

#endif  // PYSBA_GIL_H
