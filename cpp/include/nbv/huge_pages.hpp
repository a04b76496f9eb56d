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
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <limits>
#include <new>
#include <stdexcept>
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

/// A growing array of trivially copyable T (the per-voxel and per-point arrays of a mission that
/// grow to tens of millions of elements) whose buffer, from 4 MiB, is an anonymous mapping of
/// its own that grows in place by mremap: growth copies nothing and never holds an old and a new
/// buffer at once (a std::vector of 32 M voxel sums held 0.77 GB twice while it moved), and the
/// room reserved beyond size() costs no memory until written. Huge pages are asked for as in
/// HugePageAllocator. Smaller buffers live on the heap (realloc). The std::vector subset the
/// project uses: elements, size, capacity, push_back, resize, assign, reserve, clear,
/// shrink_to_fit; resize value-initialises (zeroes) the new elements.
template <class T>
class GrowArray {
  static_assert(std::is_trivially_copyable_v<T>, "GrowArray holds trivially copyable elements");

 public:
  using value_type = T;
  using iterator = T*;
  using const_iterator = const T*;

  GrowArray() = default;
  explicit GrowArray(std::size_t n, const T& v = T{}) { assign(n, v); }
  GrowArray(const GrowArray& o) { *this = o; }
  GrowArray& operator=(const GrowArray& o) {
    if (this != &o) assign(o.begin(), o.end());
    return *this;
  }
  GrowArray(GrowArray&& o) noexcept { swap(o); }
  GrowArray& operator=(GrowArray&& o) noexcept {
    if (this != &o) {
      GrowArray().swap(*this);
      swap(o);
    }
    return *this;
  }
  ~GrowArray() { release(); }
  void swap(GrowArray& o) noexcept {
    std::swap(p_, o.p_);
    std::swap(n_, o.n_);
    std::swap(cap_, o.cap_);
    std::swap(bytes_, o.bytes_);
    std::swap(mapped_, o.mapped_);
  }

  std::size_t size() const { return n_; }
  std::size_t capacity() const { return cap_; }
  bool empty() const { return n_ == 0; }
  T* data() { return p_; }
  const T* data() const { return p_; }
  T& operator[](std::size_t i) { return p_[i]; }
  const T& operator[](std::size_t i) const { return p_[i]; }
  T& back() { return p_[n_ - 1]; }
  const T& back() const { return p_[n_ - 1]; }
  T* begin() { return p_; }
  T* end() { return p_ + n_; }
  const T* begin() const { return p_; }
  const T* end() const { return p_ + n_; }

  void push_back(const T& v) {
    if (n_ == cap_) grow(n_ + 1);
    p_[n_++] = v;
  }
  void resize(std::size_t n, const T& v = T{}) {
    if (n > cap_) grow(n);
    if (n > n_) std::fill(p_ + n_, p_ + n, v);
    n_ = n;
  }
  void assign(std::size_t n, const T& v) {
    n_ = 0;
    resize(n, v);
  }
  template <class It>
  void assign(It first, It last) {
    const auto n = static_cast<std::size_t>(std::distance(first, last));
    n_ = 0;
    if (n > cap_) grow(n);
    std::copy(first, last, p_);
    n_ = n;
  }
  void clear() { n_ = 0; }
  void reserve(std::size_t n) {
    if (n > cap_) reallocate(n);
  }
  /// Gives back the room beyond size() (all of it when empty).
  void shrink_to_fit() {
    if (n_ == 0)
      release();
    else if (n_ < cap_)
      reallocate(n_);
  }

 private:
  static constexpr std::size_t kMapBytes = std::size_t(4) << 20;
  static constexpr std::size_t kHuge = std::size_t(2) << 20;

  void grow(std::size_t n) { reallocate(std::max(n, cap_ + cap_ / 2 + 16)); }
  void reallocate(std::size_t n) {
    if (n > std::numeric_limits<std::size_t>::max() / sizeof(T)) throw std::bad_alloc();
    const std::size_t want = n * sizeof(T);
    void* q = nullptr;
    std::size_t bytes = want;
    if (want >= kMapBytes) {
      bytes = (want + kHuge - 1) / kHuge * kHuge;
      if (mapped_) {
        q = mremap(p_, bytes_, bytes, MREMAP_MAYMOVE);
      } else {
        q = map_aligned(bytes);
        if (q != MAP_FAILED && n_) std::memcpy(q, p_, n_ * sizeof(T));
        if (q != MAP_FAILED) std::free(p_);
      }
      if (q == MAP_FAILED) throw std::bad_alloc();
      madvise(q, bytes, MADV_HUGEPAGE);  // a hint: failure leaves ordinary pages
      mapped_ = true;
    } else if (mapped_) {  // shrinking below the mapping's threshold: back to the heap
      q = std::malloc(want);
      if (!q) throw std::bad_alloc();
      std::memcpy(q, p_, std::min(n_, n) * sizeof(T));
      munmap(p_, bytes_);
      mapped_ = false;
    } else {
      q = std::realloc(p_, want);
      if (!q) throw std::bad_alloc();
    }
    p_ = static_cast<T*>(q);
    bytes_ = bytes;
    cap_ = bytes / sizeof(T);
    n_ = std::min(n_, cap_);
  }
  /// A fresh mapping of `bytes` (a multiple of kHuge) at a huge page boundary (the kernel backs
  /// a huge page only where one fits whole), or MAP_FAILED.
  static void* map_aligned(std::size_t bytes) {
    void* q =
        mmap(nullptr, bytes + kHuge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (q == MAP_FAILED) return q;
    const auto at = reinterpret_cast<std::uintptr_t>(q);
    const std::uintptr_t start = (at + kHuge - 1) / kHuge * kHuge;
    if (start > at) munmap(q, start - at);
    if (at + kHuge > start) munmap(reinterpret_cast<void*>(start + bytes), at + kHuge - start);
    return reinterpret_cast<void*>(start);
  }
  void release() {
    if (mapped_)
      munmap(p_, bytes_);
    else
      std::free(p_);
    p_ = nullptr;
    n_ = cap_ = bytes_ = 0;
    mapped_ = false;
  }

  T* p_ = nullptr;
  std::size_t n_ = 0, cap_ = 0, bytes_ = 0;
  bool mapped_ = false;
};

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
