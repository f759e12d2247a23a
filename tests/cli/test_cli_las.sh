#!/bin/bash
# SPDX-License-Identifier: MIT
# LAS point clouds (src/io_las.c) through the CLI: `lodkit info` on a real
# LAS 1.2 file (data/samples/las/Haystack_Rock.las, written by LAStools),
# LAS -> PLY -> LAS with the same points and bounds, a coloured PCD through
# LAS keeping its colours, and bad files (cut points, LAZ) refused with
# their byte offset and no output.
source "$(dirname "$0")/lib.sh"

S="$LK_SAMPLES_DIR/las"
expect_output_contains "format                las" "$LODKIT" info "$S/Haystack_Rock.las"
expect_output_contains "vertices              21,932" "$LODKIT" info "$S/Haystack_Rock.las"
expect_output_contains '"bbox":{"min":[2230738.75,252070.78125,-1.3159999847412109],"max":[2231104.5,252410.09375,80.81500244140625]}' \
  "$LODKIT" info --json "$S/Haystack_Rock.las"

check "convert LAS to PLY" "$LODKIT" convert "$S/Haystack_Rock.las" "$TMP/rock.ply"
check "convert PLY to LAS" "$LODKIT" convert "$TMP/rock.ply" "$TMP/rock.las"
check "a LAS 1.2 file" test "$(head -c 4 "$TMP/rock.las")" = LASF
expect_output_contains "vertices              21,932" "$LODKIT" info "$TMP/rock.las"
# x and y come back bit for bit; z within the written scale (1e-6), so the printed bounds are the same
check "same bounds after LAS -> PLY -> LAS" test \
  "$("$LODKIT" info "$TMP/rock.las" | grep bbox)" = "$("$LODKIT" info "$S/Haystack_Rock.las" | grep bbox)"

check "a coloured PCD to LAS" "$LODKIT" convert "$LK_SAMPLES_DIR/pcd/milk.pcd" "$TMP/milk.las"
expect_output_contains "attributes            colors" "$LODKIT" info "$TMP/milk.las"
check "back to PLY" "$LODKIT" convert "$TMP/milk.las" "$TMP/milk.ply"
expect_output_contains "vertices              12,575" "$LODKIT" info "$TMP/milk.ply"

# Cut in the middle of the points: refused, naming where the points start.
head -c 200000 "$S/Haystack_Rock.las" >"$TMP/cut.las"
expect_exit 1 "$LODKIT" convert "$TMP/cut.las" "$TMP/cut.ply"
expect_output_contains "cut.las: byte 331: the header claims 21932 points of 20 bytes but only 199669 bytes (9983 points) follow" \
  "$LODKIT" info "$TMP/cut.las"
check "no output from a cut file" test ! -e "$TMP/cut.ply"
# A LAZ file (LASzip sets bit 7 of the point format): how to decompress it.
{ head -c 104 "$S/Haystack_Rock.las"; printf '\x80'; tail -c +106 "$S/Haystack_Rock.las"; } >"$TMP/rock.laz"
expect_exit 1 "$LODKIT" convert "$TMP/rock.laz" "$TMP/laz.ply"
expect_output_contains "rock.laz: byte 104: the points are LAZ-compressed" "$LODKIT" info "$TMP/rock.laz"
expect_output_contains "laszip -i IN.laz -o OUT.las" "$LODKIT" info "$TMP/rock.laz"
check "no output from a LAZ file" test ! -e "$TMP/laz.ply"
finish
