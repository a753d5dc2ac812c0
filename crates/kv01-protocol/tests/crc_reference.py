# Independent reference: the KV-01 CRC pseudo-code from the source (seed 003, ch. 2.11),
# transcribed literally (unsigned char A, B, C; divide by 2; |0x80), plus the 0xF0 -> 0xF1 rule.
def crc(D):
    A = 0; B = 0; C = 0
    n = len(D)
    for i in range(n):
        A = D[i]
        for k in range(8):
            C = (A ^ B) & 0xFF
            if C & 0x01:
                C = (((B ^ 0x18) // 2) | 0x80) & 0xFF
            else:
                C = (B // 2) & 0xFF
            B = C
            if A & 0x01:
                A = ((A // 2) | 0x80) & 0xFF
            else:
                A = (A // 2) & 0xFF
    if B == 0xF0:
        B = 0xF1
    return B

def frame(addr, cmd, data):
    body = [addr, len(data) + 5, cmd] + list(data)
    return body + [crc(body), 0xF0]

def show(name, f):
    print(name, ' '.join('%02X' % b for b in f))

for name, body in [
    ("src_en", [0xE2,0x07,0xD0,0x45,0x4E]),
    ("src_ok", [0xE2,0x07,0xD0,0x4F,0x4B]),
    ("src_b1", [0xE2,0x06,0xD1,0xB1]),
    ("src_08", [0xE2,0x06,0xD1,0x08]),
]:
    print(name, 'crc=%02X' % crc(body))

show("d0_en", frame(0xE2, 0xD0, b"EN"))
show("d0_ok", frame(0xE2, 0xD0, b"OK"))
show("d1_b1", frame(0xE2, 0xD1, [0xB1]))
show("d1_08", frame(0xE2, 0xD1, [0x08]))
show("d0_v320", frame(0xE1, 0xD0, b"V320"))
show("d2_v-100", frame(0xE3, 0xD2, b"V-100"))
show("d3_req", frame(0xE4, 0xD3, []))
show("d4_req", frame(0xE5, 0xD4, []))
show("d5_req", frame(0xE6, 0xD5, [0x20 | 17]))
show("d3_rep", frame(0xE4, 0xD3, [0x12, 0x34, 0x3A]))
show("d4_rep", frame(0xE5, 0xD4, [0x03, 0x6B, 0x02, 0xFA, 0x03, 0x94]))
show("d0_timeout", frame(0xE2, 0xD0, b"TIMEOUT"))
show("d5_rep", frame(0xE6, 0xD5, [(9 << 2) | 0x3]))
show("d1_grip", frame(0xE6, 0xD1, [0x05]))
show("d0_empty", frame(0xE2, 0xD0, []))
# find small bodies whose raw CRC is 0xF0 (to test the substitution)
found = []
for a in range(0xE1, 0xE7):
    for c in range(0xD0, 0xD6):
        for d in range(256):
            body = [a, 6, c, d]
            A=0
            # raw crc without substitution
            B = 0
            for x in body:
                A = x
                for k in range(8):
                    C = (A ^ B) & 0xFF
                    B = (((B ^ 0x18)//2)|0x80) if C & 1 else B//2
                    A = ((A//2)|0x80) if A & 1 else A//2
            if B == 0xF0:
                found.append(body)
print("raw_crc_f0_examples", [' '.join('%02X'%b for b in f) for f in found[:4]])
# table of check values: crc over ASCII "123456789"
print("check_123456789 %02X" % crc(b"123456789"))
show("d4_rep_f0", frame(0xE5, 0xD4, [0x03, 0xF0, 0x02, 0xFA, 0x03, 0x94]))
show("d2_rep", frame(0xE3, 0xD2, [0x7F, 0x00, 0x25]))
show("d1_unknown77", frame(0xE1, 0xD1, [0x77]))
show("d0_limval", frame(0xE2, 0xD0, b"LIMVAL"))
