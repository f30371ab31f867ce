// An optional string that costs one pointer when absent. SubObject has seven optional text
// attributes of which a file sets one or two; std::optional<std::string> would spend 40 bytes on
// each, and the model must stay within 3x the size of the file it was read from (issue 2).
#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace cfg {

/// Behaves like std::optional<std::string> for what the model needs (has_value, *, ->, value,
/// value_or, reset, comparisons, assignment from text or nullopt). Copies are deep.
class OptionalText {
 public:
  OptionalText() = default;
  OptionalText(std::nullopt_t) {}  // NOLINT(google-explicit-constructor)
  OptionalText(std::string text)   // NOLINT(google-explicit-constructor)
      : text_(std::make_unique<std::string>(std::move(text))) {}
  OptionalText(const char* text) : OptionalText(std::string(text)) {}       // NOLINT
  OptionalText(std::string_view text) : OptionalText(std::string(text)) {}  // NOLINT
  OptionalText(const std::optional<std::string>& text) {  // NOLINT(google-explicit-constructor)
    if (text) text_ = std::make_unique<std::string>(*text);
  }
  OptionalText(const OptionalText& other)
      : text_(other.text_ ? std::make_unique<std::string>(*other.text_) : nullptr) {}
  OptionalText(OptionalText&&) noexcept = default;
  OptionalText& operator=(const OptionalText& other) {
    if (this != &other) text_ = other.text_ ? std::make_unique<std::string>(*other.text_) : nullptr;
    return *this;
  }
  OptionalText& operator=(OptionalText&&) noexcept = default;
  OptionalText& operator=(std::nullopt_t) {
    text_.reset();
    return *this;
  }
  OptionalText& operator=(std::string text) {
    text_ = std::make_unique<std::string>(std::move(text));
    return *this;
  }
  OptionalText& operator=(const char* text) { return *this = std::string(text); }
  ~OptionalText() = default;

  bool has_value() const { return text_ != nullptr; }
  explicit operator bool() const { return has_value(); }
  const std::string& operator*() const { return *text_; }
  std::string& operator*() { return *text_; }
  const std::string* operator->() const { return text_.get(); }
  std::string* operator->() { return text_.get(); }
  /// Throws std::bad_optional_access when absent, as std::optional does.
  const std::string& value() const {
    if (!text_) throw std::bad_optional_access();
    return *text_;
  }
  std::string value_or(std::string_view fallback) const {
    return text_ ? *text_ : std::string(fallback);
  }
  void reset() { text_.reset(); }
  std::string& emplace(std::string_view text) {
    text_ = std::make_unique<std::string>(text);
    return *text_;
  }
  /// Explicit on purpose: an implicit conversion would make a temporary that a string_view taken
  /// from it outlives.
  explicit operator std::optional<std::string>() const {
    return text_ ? std::optional<std::string>(*text_) : std::nullopt;
  }

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
  std::unique_ptr<std::string> text_;
};

/// For test output (GoogleTest) and logs: the text in quotes, or "nullopt".
std::ostream& operator<<(std::ostream& out, const OptionalText& text);

}  // namespace cfg
