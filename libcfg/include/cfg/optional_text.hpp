// An optional string that costs one pointer when absent. SubObject has seven optional text
// attributes of which a file sets one or two; std::optional<std::string> would spend 40 bytes on
// each, and the model must stay within 3x the size of the file it was read from.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace cfg {

class ModelArena;

/// Behaves like std::optional<std::string> for what the model needs (has_value, *, ->, value,
/// value_or, reset, comparisons, assignment from text or nullopt). Copies are deep and on the
/// heap. A text may live in a ModelArena (the reader puts values there: emplace_in): it is not
/// freed on its own but with the arena; moving such a text out (move construction or
/// assignment) copies it to the heap, so an OptionalText never depends on a model it left.
class OptionalText {
 public:
  OptionalText() = default;
  OptionalText(std::nullopt_t) {}  // NOLINT(google-explicit-constructor)
  OptionalText(std::string text)   // NOLINT(google-explicit-constructor)
      : text_(new std::string(std::move(text))) {}
  OptionalText(const char* text) : OptionalText(std::string(text)) {}       // NOLINT
  OptionalText(std::string_view text) : OptionalText(std::string(text)) {}  // NOLINT
  OptionalText(const std::optional<std::string>& text) {  // NOLINT(google-explicit-constructor)
    if (text) text_ = new std::string(*text);
  }
  OptionalText(std::optional<std::string>&& text) {  // NOLINT(google-explicit-constructor)
    if (text) text_ = new std::string(std::move(*text));
  }
  OptionalText(const OptionalText& other) : text_(other ? new std::string(*other) : nullptr) {}
  OptionalText(OptionalText&& other) noexcept { take(other); }
  OptionalText& operator=(const OptionalText& other) {
    if (this == &other) return *this;
    if (!other) return *this = std::nullopt;
    return *this = *other;
  }
  OptionalText& operator=(OptionalText&& other) noexcept {
    if (this != &other) {
      release();
      take(other);
    }
    return *this;
  }
  OptionalText& operator=(std::nullopt_t) {
    reset();
    return *this;
  }
  OptionalText& operator=(std::string text) {
    if (text_ != nullptr) {
      *get() = std::move(text);  // in place, in the arena or on the heap
    } else {
      text_ = new std::string(std::move(text));
    }
    return *this;
  }
  OptionalText& operator=(const char* text) { return *this = std::string(text); }
  ~OptionalText() { release(); }

  bool has_value() const { return text_ != nullptr; }
  explicit operator bool() const { return has_value(); }
  const std::string& operator*() const { return *get(); }
  std::string& operator*() { return *get(); }
  const std::string* operator->() const { return get(); }
  std::string* operator->() { return get(); }
  /// Throws std::bad_optional_access when absent, as std::optional does.
  const std::string& value() const {
    if (!has_value()) throw std::bad_optional_access();
    return *get();
  }
  std::string value_or(std::string_view fallback) const {
    return has_value() ? *get() : std::string(fallback);
  }
  void reset() {
    release();
    text_ = nullptr;
  }
  std::string& emplace(std::string_view text) {
    *this = std::string(text);
    return *get();
  }
  /// Sets the text, kept in `arena` (which must outlive this object and be open: not sealed).
  std::string& emplace_in(ModelArena& arena, std::string_view text);
  /// Explicit on purpose: an implicit conversion would make a temporary that a string_view taken
  /// from it outlives.
  explicit operator std::optional<std::string>() const {
    return has_value() ? std::optional<std::string>(*get()) : std::nullopt;
  }

  /// Exchanges the texts as they are (one in an arena stays there): no copy.
  friend void swap(OptionalText& a, OptionalText& b) noexcept { std::swap(a.text_, b.text_); }

  friend bool operator==(const OptionalText& a, const OptionalText& b) {
    if (a.has_value() != b.has_value()) return false;
    return !a.has_value() || *a == *b;
  }
  friend bool operator==(const OptionalText& a, std::nullopt_t) { return !a.has_value(); }
  friend bool operator==(const OptionalText& a, const std::string& b) {
    return a.has_value() && *a == b;
  }
  friend bool operator==(const OptionalText& a, const char* b) { return a.has_value() && *a == b; }
  friend bool operator==(const OptionalText& a, std::string_view b) {
    return a.has_value() && *a == b;
  }
  friend bool operator==(const OptionalText& a, const std::optional<std::string>& b) {
    return a.has_value() == b.has_value() && (!a.has_value() || *a == *b);
  }

 private:
  // The low bit of the pointer (std::string is at least 2-aligned) marks a text in an arena: a
  // tagged pointer keeps the type one pointer wide (SubObject has seven of them).
  static constexpr std::uintptr_t kInArena = 1;
  bool in_arena() const { return (reinterpret_cast<std::uintptr_t>(text_) & kInArena) != 0; }
  std::string* get() const {
    // NOLINTNEXTLINE(performance-no-int-to-ptr): the tag is cleared, the pointer is the original
    return reinterpret_cast<std::string*>(reinterpret_cast<std::uintptr_t>(text_) & ~kInArena);
  }
  void release() {
    if (text_ != nullptr && !in_arena()) delete text_;
  }
  // `other` is empty afterwards; an arena text becomes a heap copy.
  void take(OptionalText& other) {
    if (other.in_arena()) {
      text_ = new std::string(*other.get());
    } else {
      text_ = other.text_;
    }
    other.text_ = nullptr;
  }

  std::string* text_ = nullptr;  // owned unless in_arena()
};

/// For test output (GoogleTest) and logs: the text in quotes, or "nullopt".
std::ostream& operator<<(std::ostream& out, const OptionalText& text);

}  // namespace cfg
