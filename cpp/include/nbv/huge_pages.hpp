// Large, short-lived arrays backed by transparent huge pages where the kernel offers them.
//
// A fresh array of tens of megabytes (glibc maps every allocation over 32 MB anew, and unmaps it
// when freed) costs a page fault per 4 KiB page when first written. On this project's virtual
// machine a fault costs about 4 microseconds, so filling a 60 MB scratch array spent more time in
// the kernel than in the loop that filled it. Asking for huge pages (MADV_HUGEPAGE, honoured
// where /sys/kernel/mm/transparent_hugepage/enabled is "madvise" or "always") makes that one
// fault per 2 MiB. Elsewhere the advice is ignored and nothing changes.
#pragma once

#include <sys/mman.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace nbv {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr std::size_t kHuge = std::size_t(2) << 20;  // one huge page
  static constexpr std::size_t kMin = 4 * kHuge;              // smaller arrays: plain operator new

  HugePageAllocator() = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) {}  // NOLINT: rebinding

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kMin) return static_cast<T*>(::operator new(bytes));
    const std::size_t size = (bytes + kHuge - 1) / kHuge * kHuge;
    void* p = std::aligned_alloc(kHuge, size);
    if (!p) throw std::bad_alloc();
    madvise(p, size, MADV_HUGEPAGE);  // a hint: failure leaves ordinary pages
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) {
    if (n * sizeof(T) < kMin)
      ::operator delete(p);
    else
      std::free(p);
  }
  template <class U>
  bool operator==(const HugePageAllocator<U>&) const {
    return true;
  }
  template <class U>
  bool operator!=(const HugePageAllocator<U>&) const {
    return false;
  }
};

/// A std::vector whose large buffers ask for huge pages.
template <class T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

/// HugePageAllocator whose value-initialisation (resize(n), vector(n)) leaves trivial elements
/// uninitialised: for an array that is filled right after, in parallel, so that its pages are
/// first touched (and zeroed by the kernel) by the threads that fill them, not by one memset.
template <class T>
struct UninitHugePageAllocator : HugePageAllocator<T> {
  template <class U>
  struct rebind {
    using other = UninitHugePageAllocator<U>;
  };
  UninitHugePageAllocator() = default;
  template <class U>
  UninitHugePageAllocator(const UninitHugePageAllocator<U>&) {}  // NOLINT: rebinding
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;  // default-initialised: no zeroing for trivial types
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A HugeVector whose resize leaves trivial elements uninitialised (UninitHugePageAllocator):
/// every element must be written before it is read.
template <class T>
using HugeBuffer = std::vector<T, UninitHugePageAllocator<T>>;

/// A zero-filled array of n trivial T in an anonymous mapping of its own, whose pages can all be
/// handed back to the kernel at once (release): every element then reads zero again, and a page
/// costs memory only once it is written again. For scratch indexed by a large id space of which
/// one use touches a small part (the integration's per-cell stamps of a 77 M-cell grid): its
/// memory is what one use touched, not what every use ever touched, and a fresh one costs
/// nothing until written.
template <class T>
class ReleasableArray {
  static_assert(std::is_trivially_copyable_v<T>, "ReleasableArray holds trivial elements");

 public:
  ReleasableArray() = default;
  explicit ReleasableArray(std::size_t n) : n_(n) {
    if (n == 0) return;
    void* p = mmap(nullptr, bytes(), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    // ordinary pages also where huge pages are "always": a use touches scattered cells, and
    // a 2 MiB page zeroed again after every release would cost more than it saves
    madvise(p, bytes(), MADV_NOHUGEPAGE);
    p_ = static_cast<T*>(p);
  }
  ReleasableArray(ReleasableArray&& o) noexcept
      : p_(std::exchange(o.p_, nullptr)), n_(std::exchange(o.n_, 0)) {}
  ReleasableArray& operator=(ReleasableArray&& o) noexcept {
    if (this != &o) {
      unmap();
      p_ = std::exchange(o.p_, nullptr);
      n_ = std::exchange(o.n_, 0);
    }
    return *this;
  }
  ReleasableArray(const ReleasableArray&) = delete;
  ReleasableArray& operator=(const ReleasableArray&) = delete;
  ~ReleasableArray() { unmap(); }

  T* data() const { return p_; }
  T& operator[](std::size_t i) const { return p_[i]; }
  std::size_t size() const { return n_; }
  explicit operator bool() const { return p_ != nullptr; }
  /// Every element reads zero again; the pages written so far no longer count as memory.
  void release() {
    if (p_ && madvise(p_, bytes(), MADV_DONTNEED) != 0)
      std::fill(p_, p_ + n_, T{});  // (not expected: the mapping is private and anonymous)
  }

 private:
  std::size_t bytes() const { return n_ * sizeof(T); }
  void unmap() {
    if (p_) munmap(p_, bytes());
    p_ = nullptr;
  }
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

}  // namespace nbv
