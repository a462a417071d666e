// The header of qota 0.2: qota/pixel_window.hpp (qota::CellWindow is qota::PixelWindow).
#pragma once

#include "qota/pixel_window.hpp"
