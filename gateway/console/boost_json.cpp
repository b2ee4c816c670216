// Boost.JSON's implementation, compiled once for the daemon (Debian's libboost1.81-dev ships it
// as headers; no libboost_json is linked).
#include <boost/json/src.hpp>
