// Instants that users type: an ISO 8601 date and time with its UTC offset, or a local time in a
// time zone (an offset, or an IANA name such as Europe/Paris through the system's tz database,
// with Howard Hinnant's date/tz library).
//
// Rules:
// - Text: YYYY-MM-DD, then optionally T (or a space) and HH:MM[:SS[.fff]], then optionally an
//   offset: Z, +HH:MM, -HH:MM, +HHMM or +HH. Every field is checked: 2024-02-30, 24:00, 12:60 and
//   60 seconds are errors, never carried into the next day or hour.
// - Zone: an instant needs one. Either the text carries its offset, or `zone` gives it (an
//   offset as above, "UTC", or an IANA name); giving both is an error (which one was meant?).
//   Without either it is an error: "12:00" means nothing until one says where.
// - A local time that a daylight-saving change skips (02:30 on a spring-forward night) or
//   repeats (01:30 on a fall-back night) is an error asking for an explicit offset.
// Errors are qota::Error naming the text.
#pragma once

#include <string>
#include <string_view>

namespace qota {

struct Instant {
  double julianDayUT = 0;  // days since -4712-01-01T12:00 UT
  std::string utc;         // the instant in UTC, "2024-06-22T01:30:00Z"
  std::string local;       // as given, with the offset it was read with ("2024-06-21T18:30-07:00")
};

// The instant of a date and time. The date alone is its local midnight.
Instant parseInstant(std::string_view text, std::string_view zone = {});

// The date part of an ISO 8601 text, checked: "2024-06-21".
std::string isoDate(std::string_view text);

// The instants of the local clock times start and end (hours after local midnight, 0 to 48) of a
// date in a zone (the offset written in `text` or `zone`, as parseInstant): for sampling over
// part of a local day. On a daylight-saving day the clock hours and the elapsed hours differ;
// the returned instants are the true ones.
struct LocalSpan {
  Instant start, end;
};
LocalSpan localSpan(std::string_view text, std::string_view zone, double startHour, double endHour);

// The Julian day (UT) of a Unix time in seconds, and back as ISO 8601 UTC text.
double julianDayOfUnix(double seconds);
std::string utcText(double julianDayUT);

}  // namespace qota
