#!/bin/sh
# Writes a man page (roff) for one of i2m's programs from its own --help, so that the page
# and the program never disagree:  sh tools/man.sh PROGRAM NAME "one-line summary" > NAME.1
# The help's first line is the synopsis; lines that begin with two spaces and an option or an
# argument become tagged paragraphs (their deeper-indented continuation lines join them);
# other lines are paragraphs of their own.
set -eu
prog=$1 name=$2 summary=$3
"$prog" --help 2>&1 | awk -v name="$name" -v summary="$summary" -v date="$(date -u +%Y-%m-%d)" '
function esc(s) { gsub(/\\/, "\\e", s); gsub(/-/, "\\-", s); if (s ~ /^[.\047]/) s = "\\&" s; return s }
function flush() { if (tag != "") { print ".TP"; print "\\fB" esc(tag) "\\fR"; print esc(text) } tag = ""; text = "" }
BEGIN {
  print ".TH " toupper(name) " 1 \"" date "\" \"i2m 0.1\" \"User Commands\""
  print ".SH NAME"; print name " \\- " summary
}
NR == 1 { sub(/^usage: */, ""); print ".SH SYNOPSIS"; print ".B " esc($0); print ".SH DESCRIPTION"; next }
/^  [^ ]/ {
  flush()
  line = substr($0, 3)
  if (match(line, /  +/)) { tag = substr(line, 1, RSTART - 1); text = substr(line, RSTART + RLENGTH) }
  else { tag = line; text = "" }
  next
}
/^      / && tag != "" { t = $0; sub(/^ +/, "", t); text = text (text == "" ? "" : " ") t; next }
{ flush(); t = $0; sub(/^ +/, "", t); if (t != "") { print ".PP"; print esc(t) } }
END {
  flush()
  print ".SH SEE ALSO"
  print "i2m(1), i2m\\-check(1), i2m\\-info(1); the README of the i2m source tree."
}'
