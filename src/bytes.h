/* SPDX-License-Identifier: MIT */
/* Little-endian loads and stores of fixed-size fields, whatever the byte
 * order of the machine: every binary format lodkit reads or writes stores
 * its numbers little-endian (.lks streams, GLB and glTF buffers, MD2,
 * binary STL, zip members of .npz, the server's LKMB buffers). One copy,
 * inlined where it is used. Floats are IEEE 754 binary32/binary64 (what C11
 * Annex F and every platform lodkit builds on use); their bits move through
 * memcpy, never through a cast. Not installed. */
#ifndef LODKIT_BYTES_H
#define LODKIT_BYTES_H

#include <stdint.h>
#include <string.h>

static inline uint16_t lk__load_u16le(const unsigned char *p) { return (uint16_t)(p[0] | p[1] << 8); }

static inline uint32_t lk__load_u32le(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint64_t lk__load_u64le(const unsigned char *p)
{
    return (uint64_t)lk__load_u32le(p) | (uint64_t)lk__load_u32le(p + 4) << 32;
}

/* Two's complement, decoded by arithmetic (no implementation-defined
 * conversion of an out-of-range unsigned value). */
static inline int16_t lk__load_i16le(const unsigned char *p)
{
    int32_t bits = lk__load_u16le(p);
    return (int16_t)(bits < 0x8000 ? bits : bits - 0x10000);
}

static inline int32_t lk__load_i32le(const unsigned char *p)
{
    uint32_t bits = lk__load_u32le(p);
    return bits < 0x80000000u ? (int32_t)bits : -(int32_t)~bits - 1;
}

static inline float lk__load_f32le(const unsigned char *p)
{
    uint32_t bits = lk__load_u32le(p);
    float value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

static inline double lk__load_f64le(const unsigned char *p)
{
    uint64_t bits = lk__load_u64le(p);
    double value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

static inline void lk__store_u16le(unsigned char *p, uint16_t value)
{
    p[0] = (unsigned char)value;
    p[1] = (unsigned char)(value >> 8);
}

static inline void lk__store_u32le(unsigned char *p, uint32_t value)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(value >> (8 * i));
}

static inline void lk__store_u64le(unsigned char *p, uint64_t value)
{
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(value >> (8 * i));
}

static inline void lk__store_i32le(unsigned char *p, int32_t value)
{
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    lk__store_u32le(p, bits);
}

static inline void lk__store_f32le(unsigned char *p, float value)
{
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    lk__store_u32le(p, bits);
}

static inline void lk__store_f64le(unsigned char *p, double value)
{
    uint64_t bits;
    memcpy(&bits, &value, sizeof bits);
    lk__store_u64le(p, bits);
}

/* A little-endian number of `size` bytes (1, 2, 4 or 8; 4 or 8 for floats)
 * as a double: kind 'f' a float, 'u' an unsigned, 'i' a signed
 * (two's-complement) integer. The typed fields of PCD records and NumPy
 * arrays. */
static inline double lk__load_number_le(const unsigned char *p, unsigned size, char kind)
{
    uint64_t bits = 0;
    for (unsigned k = 0; k < size; k++) bits |= (uint64_t)p[k] << (8 * k);
    if (kind == 'f') {
        if (size == 4) {
            uint32_t bits32 = (uint32_t)bits;
            float value;
            memcpy(&value, &bits32, 4);
            return value;
        }
        double value;
        memcpy(&value, &bits, 8);
        return value;
    }
    if (kind == 'u') return (double)bits;
    unsigned shift = 64 - 8 * size; /* sign-extend */
    return (double)((int64_t)(bits << shift) >> shift);
}

#endif
