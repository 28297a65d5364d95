#pragma once
// Internal: GraphWorkspace's per-thread buffers (clique.hpp).
#include <binpose/clique.hpp>

#include <any>
#include <tbb/enumerable_thread_specific.h>

namespace binpose {

struct GraphWorkspace::Impl {
  tbb::enumerable_thread_specific<std::any> buffers;

  /// This thread's buffer of type T, made on first use and kept for the next graph.
  template <class T>
  T& local() {
    std::any& a = buffers.local();
    if (T* t = std::any_cast<T>(&a)) return *t;
    return a.emplace<T>();
  }
};

}  // namespace binpose
