// numpy helpers shared by the extension modules: read-only views into C++ buffers kept alive by a
// Python owner, arrays that take over a std::vector without copying, and argument checks whose
// errors name the argument.
#pragma once

#include <cstdint>
#include <cstring>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "common/error.h"

namespace lmb::python {

namespace py = pybind11;

// Raises the Python exception `type` with an lmb::Error's message. The message need not be UTF-8
// (it may quote a damaged file's bytes): bytes that are not become \xNN escapes instead of an
// exception without its message.
inline void raise_error(PyObject* type, const char* what) {
  PyObject* message = PyUnicode_DecodeUTF8(what, static_cast<Py_ssize_t>(std::strlen(what)), "backslashreplace");
  if (message == nullptr) {
    PyErr_Clear();
    PyErr_SetString(type, "(an error whose message cannot be decoded)");
    return;
  }
  PyErr_SetObject(type, message);
  Py_DECREF(message);
}

// Makes lmb::Error thrown in this extension module raise landmarkboost._core.Error (for the
// modules other than _core, which defines it).
inline void translate_errors_to_core_error() {
  static py::object error = py::module_::import("landmarkboost._core").attr("Error");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      raise_error(error.ptr(), e.what());
    }
  });
}

// A read-only array over `data` (shape and byte strides given) that keeps `owner` alive.
template <class T>
py::array_t<T> view(const T* data, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides, py::handle owner) {
  py::array_t<T> a(std::move(shape), std::move(strides), data, owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

// A 1-D read-only view of `count` contiguous T.
template <class T>
py::array_t<T> view(const T* data, size_t count, py::handle owner) {
  return view<T>(data, {static_cast<py::ssize_t>(count)}, {static_cast<py::ssize_t>(sizeof(T))}, owner);
}

// An array that owns `v` (moved, not copied), with the given shape (row-major).
template <class T>
py::array_t<T> take(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  auto* heap = new std::vector<T>(std::move(v));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(std::move(shape), heap->data(), owner);
}

// A vector<char> of 0/1 as a read-only numpy bool view.
inline py::array bool_view(const std::vector<char>& v, py::handle owner) {
  py::array a(py::dtype("bool"), {static_cast<py::ssize_t>(v.size())}, {static_cast<py::ssize_t>(1)}, v.data(), owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

// "float64 array of shape (3, 4)" for error messages.
inline std::string describe(const py::array& a) {
  std::string s = py::str(a.dtype()).cast<std::string>() + " array of shape (";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

}  // namespace lmb::python
