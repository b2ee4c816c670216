// What a unit answers to Modbus "read device identification" (FC 0x2B/0x0E).
#pragma once

#include "gateway/image/process_image.hpp"
#include "gateway/modbus/pdu.hpp"
#include "mapping/register_map.hpp"

namespace fieldgate {

// Basic objects: the controller's vendor (by protocol family; for CANopen the identity
// object's vendor ID once read), product code (the model, plus the controller's own product
// code where the model reads one) and revision (the controller's revision number where read,
// else the gateway's version). Regular objects: product name (the model's description), model
// name, and the node and bus as the user application name.
modbus::DeviceIdentification identify(const UnitMap& unit, const NodeImage& node);

}  // namespace fieldgate
