#!/bin/sh
# A launcher prefix for the tests, shaped like mpirun: it starts the rest of
# its command line as a child (not exec), logs a line, and exits with the
# child's status. cosim appends --endpoint EP --name NAME to the whole list.
echo "launcher: starting $*" >&2
"$@" &
wait $!
