#pragma once

#include "gateway/control/control_result.hpp"
#include "gateway/modbus/pdu.hpp"

namespace fieldgate {

// The Modbus exception a control result answers a write with (its one mapping, shared by the
// register map and the axis profile, over TCP and RTU).
modbus::ExceptionCode exception_for(ControlStatus status);

}  // namespace fieldgate
