"""pymodbus steps shared by the foreign-master checks (foreign_clients.sh over TCP,
rtu_masters.sh over RTU); lib.sh puts this folder on PYTHONPATH."""
import time


def move_to_2500(client, ok, label):
    """Enables unit 2 (a Copley amplifier of the demo map), moves it to 2500 and checks that it
    got there; ok(name, condition) reports each step."""
    r = client.write_register(100, 1, slave=2)           # enable
    ok(label + ": enable confirmed (%s)" % r, not r.isError())
    r = client.write_registers(110, [0, 2500], slave=2)  # target 2500
    ok(label + ": target written (%s)" % r, not r.isError())
    r = client.write_register(100, 3, slave=2)           # move_absolute
    ok(label + ": move confirmed (%s)" % r, not r.isError())
    for _ in range(200):
        r = client.read_holding_registers(101, 1, slave=2)
        if not r.isError() and r.registers[0] == 2:
            break
        time.sleep(0.05)
    pos = client.read_input_registers(0, 2, slave=2).registers
    ok(label + ": position reached 2500 (%s)" % pos, pos == [0, 2500])
