#!/usr/bin/env python3
# The sink's memory under hostile peers, on loopback: starts `voxwall sink` for a wall and prints its
# resident memory idle, with 10 peers that claim 64 MiB before Hello, 10 greeted peers that claim
# 64 MiB and send nothing, and 10 one-pixel tiles for 10 frame ids. Run it with two binaries to
# compare builds (VERSION is the wire protocol version the binary speaks: 1 before job ids, 2).
#   /usr/bin/python3 bench/sink_memory.py build/master/voxwall walls/bigeye.json 2
import ctypes, socket, struct, subprocess, sys, time, re, os
xx = ctypes.CDLL("libxxhash.so.0"); xx.XXH32.restype = ctypes.c_uint32
xx.XXH32.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint32]
if len(sys.argv) != 4:
    sys.exit("usage: sink_memory.py VOXWALL WALL.json PROTOCOL_VERSION")
VERSION = int(sys.argv[3])
def msg(mtype, frame, payload, claimed=None):
    n = len(payload) if claimed is None else claimed
    head = struct.pack("<IHHIIQI", 0x50575756, VERSION, mtype, 0, n, frame, xx.XXH32(payload, len(payload), 0))
    return head + struct.pack("<I", xx.XXH32(head, 28, 0)) + payload
def s(t): b = t.encode(); return struct.pack("<H", len(b)) + b
def hello(job): return msg(1, 0, (struct.pack("<BiiQQ", 1, 0, 1, job, 0) if VERSION == 2 else struct.pack("<Bii", 1, 0, 1)) + s("bigeye") + s(""))
def tile(frame, x):
    rgb = b"\x80\x80\x80"
    return msg(3, frame, struct.pack("<iiiiBQ", x, 0, 1, 1, 2, 0) + rgb)  # codec 2 = raw
def rss(pid):
    st = open(f"/proc/{pid}/status").read()
    return [int(re.search(k + r":\s+(\d+)", st).group(1)) // 1024 for k in ("VmRSS", "VmHWM")]
voxwall, wall = sys.argv[1], sys.argv[2]
p = subprocess.Popen([voxwall, "sink", "--wall", wall, "--listen", "127.0.0.1:0", "--no-stdin"], stdout=subprocess.PIPE, text=True)
first = p.stdout.readline()
m = re.search(r"127.0.0.1:(\d+)", first)
if not m: sys.exit("sink_memory: cannot read the port from: " + first.strip())
port = int(m.group(1))
time.sleep(0.3)
print("idle sink: RSS %d MiB (peak %d)" % tuple(rss(p.pid)))
conns = []
for i in range(10):
    c = socket.create_connection(("127.0.0.1", port)); c.sendall(msg(1, 0, b"", claimed=64 << 20)[:32]); conns.append(c)
time.sleep(1)
print("10 peers claiming 64 MiB before Hello: RSS %d MiB (peak %d)" % tuple(rss(p.pid)))
for c in conns: c.close()
conns = []
for i in range(10):
    c = socket.create_connection(("127.0.0.1", port)); c.sendall(hello(1)); c.recv(4096)
    c.sendall(msg(3, 1, b"", claimed=64 << 20)[:32]); conns.append(c)
time.sleep(1)
print("10 greeted peers claiming 64 MiB, sending nothing: RSS %d MiB (peak %d)" % tuple(rss(p.pid)))
for c in conns: c.close()
time.sleep(0.5)
c = socket.create_connection(("127.0.0.1", port)); c.sendall(hello(1)); c.recv(4096)
for f in range(10): c.sendall(tile(f, f))
time.sleep(1)
print("10 one-pixel tiles for 10 frame ids (bigeye, --pending 4): RSS %d MiB (peak %d)" % tuple(rss(p.pid)))
p.terminate(); p.wait()
