#!/bin/sh
# station.sh SERIAL POSE_DIR: calibrate one unit from POSE_DIR/x.csv, y.csv and z.csv.
# Keeps every computed calibration (pass or fail) in cals/, and tells the operator what next
# from tumblecal's exit status: 0 pass, 1 outside its limits, 3 capture rejected, 2 set-up error.
serial="$1"
poses="$2"
limits="${LIMITS:-sample_data/limits.yaml}"
mkdir -p cals logs
tumblecal solve --poses "$poses/x.csv" "$poses/y.csv" "$poses/z.csv" \
    --limits "$limits" --serial "$serial" --station "${STATION:-bay-1}" \
    -o "cals/$serial.json" --json --quiet > "logs/$serial.json" 2> "logs/$serial.err"
status=$?
case $status in
    0) echo "$serial: PASS, calibration in cals/$serial.json" ;;
    1) echo "$serial: FAIL, outside $(jq -r '[.verdict.failures[].code] | join(", ")' "logs/$serial.json")" ;;
    3) echo "$serial: RETEST, $(jq -r '[.rejections[].code] | unique | join(", ")' "logs/$serial.json"):"
       sed 's/^/  /' "logs/$serial.err" ;;
    *) echo "$serial: STATION ERROR (exit $status), stop the line:"
       sed 's/^/  /' "logs/$serial.err" ;;
esac
exit "$status"
