"""Input and output: the frame reader, the annotated-video sink and its drawing, MOTChallenge
and JSON-lines box files, and atomic (temporary name, then rename) writes.

Import the modules themselves (``fastdet.io.reader``, ``fastdet.io.motfiles`` ...): this
package imports nothing, so a module that needs only :mod:`fastdet.io.atomic` stays light."""
