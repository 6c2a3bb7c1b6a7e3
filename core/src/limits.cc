#include "magnav/core/limits.h"

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"

namespace magnav {

namespace {

static_assert([] {
  for (std::size_t i = 0; i < kLimits.size(); ++i) {
    if (kLimits[i].id != static_cast<int>(i)) return false;
  }
  return true;
}(), "Limit::id must be the limit's index in kLimits");

// The site's value per limit, NaN = the default. Read on every check (atomic:
// a reader thread may check while a test resets them); written at start.
struct SiteTable {
  std::array<std::atomic<double>, kLimits.size()> value;
  SiteTable() {
    for (auto& v : value) v.store(std::numeric_limits<double>::quiet_NaN());
  }
};
SiteTable g_site;
std::mutex g_source_mu;
std::string g_source;  // where the site limits came from

const Limit* FindKey(const std::string& key) {
  for (const Limit& l : kLimits) {
    if (key == l.key) return &l;
  }
  return nullptr;
}

std::string KeyList() {
  std::string s;
  for (const Limit& l : kLimits) s += (s.empty() ? "" : ", ") + std::string(l.key);
  return s;
}

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

}  // namespace

double MaxAbs(const Limit& limit) {
  if (limit.id < 0 || limit.id >= static_cast<int>(kLimits.size())) return limit.max_abs;
  const double site = g_site.value[static_cast<std::size_t>(limit.id)].load(std::memory_order_relaxed);
  return std::isnan(site) ? limit.max_abs : site;
}

std::string LimitWhy(const Limit& limit) {
  if (MaxAbs(limit) == limit.max_abs) return limit.why;
  std::lock_guard<std::mutex> lk(g_source_mu);
  return "site limit from " + g_source + "; default " + FormatNumber(limit.max_abs) + " " + limit.unit;
}

std::string OutOfRange(const Limit& limit, double value) {
  return FormatNumber(value) + " " + limit.unit + " is out of range (|value| > " + FormatNumber(MaxAbs(limit)) + " " +
         limit.unit + "; " + LimitWhy(limit) + ")";
}

void SetSiteLimits(const std::vector<std::pair<std::string, double>>& values, const std::string& source) {
  std::array<double, kLimits.size()> next;
  next.fill(std::numeric_limits<double>::quiet_NaN());
  for (const auto& [key, value] : values) {
    const Limit* l = FindKey(key);
    if (!l) throw InputError(source + ": unknown limit '" + key + "' (known: " + KeyList() + ")");
    if (!std::isfinite(value) || value <= 0.0) {
      throw InputError(source + ": limit '" + key + "' = " + FormatNumber(value) + ": must be a finite number > 0");
    }
    if (!std::isnan(next[static_cast<std::size_t>(l->id)])) {
      throw InputError(source + ": limit '" + key + "' given twice");
    }
    next[static_cast<std::size_t>(l->id)] = value;
  }
  {
    std::lock_guard<std::mutex> lk(g_source_mu);
    g_source = source;
  }
  for (std::size_t i = 0; i < next.size(); ++i) g_site.value[i].store(next[i]);
}

void LoadSiteLimits(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path + ": a directory, not a site limits file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the site limits file");
  std::vector<std::pair<std::string, double>> values;
  // Lines are short and few: a longer line or file is not a limits file
  // (/dev/zero, a binary file) and is refused without reading it all.
  constexpr int kMaxLine = 4096, kMaxLines = 1000;
  char buf[kMaxLine];
  int n = 0;
  while (in.getline(buf, kMaxLine) || in.gcount() > 0) {
    ++n;
    const std::string where = path + ":" + std::to_string(n) + ": ";
    if (in.fail() && !in.eof()) throw InputError(where + "line longer than " + std::to_string(kMaxLine - 1) + " bytes");
    if (n > kMaxLines) throw InputError(where + "more than " + std::to_string(kMaxLines) + " lines");
    std::string t = Trim(buf);
    if (t.empty() || t[0] == '#' || t[0] == ';') continue;
    if (t == "[limits]") continue;
    if (t[0] == '[') throw InputError(where + "section " + t + ": a site limits file has only [limits]");
    const auto eq = t.find('=');
    if (eq == std::string::npos) throw InputError(where + "expected 'key = value', got '" + t + "'");
    const std::string key = Trim(t.substr(0, eq));
    std::string text = Trim(t.substr(eq + 1));
    if (const auto hash = text.find('#'); hash != std::string::npos) text = Trim(text.substr(0, hash));
    const auto value = ParseNumber(text);
    if (!value) throw InputError(where + "limit '" + key + "': '" + text + "' is not a number");
    values.emplace_back(key, *value);
  }
  SetSiteLimits(values, path);
}

void ResetSiteLimits() { SetSiteLimits({}, ""); }

std::vector<std::string> DescribeSiteLimits() {
  std::vector<std::string> out;
  std::string source;
  {
    std::lock_guard<std::mutex> lk(g_source_mu);
    source = g_source;
  }
  for (const Limit& l : kLimits) {
    const double m = MaxAbs(l);
    if (m != l.max_abs) {
      out.push_back(std::string(l.key) + " = " + FormatNumber(m) + " " + l.unit + " (site limit from " + source +
                    "; default " + FormatNumber(l.max_abs) + ")");
    }
  }
  return out;
}

}  // namespace magnav
