#include "qota/instant.hpp"

#include <date/date.h>
#include <date/tz.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "qota/error.hpp"

namespace qota {
namespace {

using Micros = std::chrono::microseconds;

[[noreturn]] void bad(std::string_view text, const std::string& why) {
  throw Error("time '" + std::string(text) + "': " + why +
              " (expected YYYY-MM-DD[THH:MM[:SS]][Z|+HH:MM], e.g. 2024-06-21T14:30+02:00)");
}

// n digits at s[pos], as a number; -1 when they are not all digits.
int digits(std::string_view s, std::size_t pos, std::size_t n) {
  if (pos + n > s.size()) return -1;
  int v = 0;
  for (std::size_t i = pos; i < pos + n; ++i) {
    if (s[i] < '0' || s[i] > '9') return -1;
    v = v * 10 + (s[i] - '0');
  }
  return v;
}

// Z, +HH:MM, -HH:MM, +HHMM, +HH (and UTC): the offset in minutes; nullopt when `s` is not one.
std::optional<int> offsetMinutes(std::string_view s) {
  if (s == "Z" || s == "z" || s == "UTC") return 0;
  if (s.size() < 3 || (s[0] != '+' && s[0] != '-')) return std::nullopt;
  const int h = digits(s, 1, 2);
  int m = 0;
  if (s.size() == 6 && s[3] == ':') {
    m = digits(s, 4, 2);
  } else if (s.size() == 5) {
    m = digits(s, 3, 2);
  } else if (s.size() != 3) {
    return std::nullopt;
  }
  if (h < 0 || m < 0 || h > 18 || m > 59) return std::nullopt;
  return (s[0] == '-' ? -1 : 1) * (h * 60 + m);
}

std::string offsetText(int minutes) {
  const int a = std::abs(minutes);
  char buf[16];
  std::snprintf(buf, sizeof buf, "%c%02d:%02d", minutes < 0 ? '-' : '+', a / 60, a % 60);
  return buf;
}

struct Written {
  date::year_month_day day{};
  Micros timeOfDay{0};
  std::optional<int> offset;  // minutes, when the text carries one
};

Written parseWritten(std::string_view text) {
  Written w;
  const int y = digits(text, 0, 4), mo = digits(text, 5, 2), d = digits(text, 8, 2);
  if (y < 0 || mo < 0 || d < 0 || text.size() < 10 || text[4] != '-' || text[7] != '-') {
    bad(text, "not a date");
  }
  w.day = date::year{y} / date::month{static_cast<unsigned>(mo)} / date::day{static_cast<unsigned>(d)};
  if (!w.day.ok()) bad(text, "no such date");
  std::size_t pos = 10;
  if (pos < text.size() && (text[pos] == 'T' || text[pos] == 't' || text[pos] == ' ')) {
    const int h = digits(text, pos + 1, 2), mi = digits(text, pos + 4, 2);
    if (h < 0 || mi < 0 || text.size() < pos + 6 || text[pos + 3] != ':') bad(text, "not a time of day");
    if (h > 23) bad(text, "hour " + std::to_string(h) + " is not 00 to 23");
    if (mi > 59) bad(text, "minute " + std::to_string(mi) + " is not 00 to 59");
    Micros t = std::chrono::hours(h) + std::chrono::minutes(mi);
    pos += 6;
    if (pos < text.size() && text[pos] == ':') {
      const int s = digits(text, pos + 1, 2);
      if (s < 0) bad(text, "bad seconds");
      if (s > 59) bad(text, "second " + std::to_string(s) + " is not 00 to 59");
      t += std::chrono::seconds(s);
      pos += 3;
      if (pos < text.size() && (text[pos] == '.' || text[pos] == ',')) {
        std::size_t end = pos + 1;
        long long frac = 0, scale = 1000000;
        while (end < text.size() && text[end] >= '0' && text[end] <= '9') {
          if (scale > 1) frac = frac * 10 + (text[end] - '0'), scale /= 10;
          ++end;
        }
        if (end == pos + 1) bad(text, "bad fraction of a second");
        t += Micros(frac * scale);
        pos = end;
      }
    }
    w.timeOfDay = t;
  }
  if (pos < text.size()) {
    w.offset = offsetMinutes(text.substr(pos));
    if (!w.offset) bad(text, "'" + std::string(text.substr(pos)) + "' is not a UTC offset");
  }
  return w;
}

// Where a local time is: a fixed offset or a zone of the tz database.
struct Zone {
  std::optional<int> offset;
  const date::time_zone* tz = nullptr;
  std::string name;
};

Zone zoneOf(std::string_view text, const Written& w) {
  if (w.offset && !text.empty()) {
    throw Error("time carries its UTC offset and --tz '" + std::string(text) + "' gives another: give only one");
  }
  if (w.offset) return {w.offset, nullptr, offsetText(*w.offset)};
  if (text.empty()) {
    throw Error(
        "no UTC offset: add Z or +HH:MM to the time, or give --tz (an offset such as "
        "-07:00, or a zone name such as America/Los_Angeles)");
  }
  if (const auto m = offsetMinutes(text)) return {m, nullptr, offsetText(*m)};
  try {
    const std::string name(text);
    return {std::nullopt, date::locate_zone(name), name};
  } catch (const std::exception&) {
    throw Error("time zone '" + std::string(text) +
                "': not an offset (+HH:MM) nor a zone name "
                "the system's tz database knows (such as Europe/Paris; tzdata installed?)");
  }
}

// ISO 8601 text of a time point, without trailing zero decimals.
template <class TimePoint>
std::string isoText(const TimePoint& t) {
  std::string s = date::format("%FT%T", t);  // microseconds: six decimals
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s;
}
std::string localText(const date::local_time<Micros>& t) { return isoText(t); }

// The true instant of a local time in a zone.
date::sys_time<Micros> toSys(const date::local_time<Micros>& local, const Zone& zone, std::string_view text) {
  if (zone.offset) return date::sys_time<Micros>{local.time_since_epoch()} - std::chrono::minutes(*zone.offset);
  const date::local_info info = zone.tz->get_info(local);
  switch (info.result) {
    case date::local_info::unique:
      return date::sys_time<Micros>{local.time_since_epoch()} - info.first.offset;
    case date::local_info::nonexistent:
      throw Error("time '" + std::string(text) + "': " + localText(local) + " does not exist in " + zone.name +
                  " (the clocks skip it); give an explicit UTC offset");
    default:
      throw Error("time '" + std::string(text) + "': " + localText(local) + " happens twice in " + zone.name + " (" +
                  offsetText(static_cast<int>(info.first.offset.count() / 60)) + " and " +
                  offsetText(static_cast<int>(info.second.offset.count() / 60)) + "); give an explicit UTC offset");
  }
}

std::string trimmedIso(const date::sys_time<Micros>& t) { return isoText(t) + "Z"; }

Instant instantOf(const date::sys_time<Micros>& t, std::string local) {
  const double seconds = static_cast<double>(t.time_since_epoch().count()) * 1e-6;
  return {julianDayOfUnix(seconds), trimmedIso(t), std::move(local)};
}

}  // namespace

double julianDayOfUnix(double seconds) { return 2440587.5 + seconds / 86400.0; }

std::string utcText(double julianDayUT) {
  const double micros = std::round((julianDayUT - 2440587.5) * 86400e6);
  return trimmedIso(date::sys_time<Micros>{Micros(static_cast<long long>(micros))});
}

std::string isoDate(std::string_view text) {
  const Written w = parseWritten(text);
  return date::format("%F", w.day);
}

Instant parseInstant(std::string_view text, std::string_view zoneText) {
  const Written w = parseWritten(text);
  const Zone zone = zoneOf(zoneText, w);
  const date::local_time<Micros> local = date::local_days{w.day} + w.timeOfDay;
  const date::sys_time<Micros> t = toSys(local, zone, text);
  std::string shown = std::string(text);
  if (!w.offset) shown += " " + zone.name;
  return instantOf(t, shown);
}

LocalSpan localSpan(std::string_view text, std::string_view zoneText, double startHour, double endHour) {
  const Written w = parseWritten(text);
  const Zone zone = zoneOf(zoneText, w);
  const auto at = [&](double hour) {
    const Micros since(static_cast<long long>(std::llround(hour * 3600e6)));
    const date::local_time<Micros> local = date::local_days{w.day} + since;
    return instantOf(toSys(local, zone, text), localText(local) + " " + zone.name);
  };
  return {at(startHour), at(endHour)};
}

}  // namespace qota
