# help2man fills the lines under "Examples:" into paragraphs; keep them one command a line, as
# --help prints them (a command with a comment after it became a .TP pair: join it again).
/^\.SH EXAMPLES$/,/^\.S[SH] /{
  /^\.TP$/{
    N
    N
    s/^\.TP\n\(.*\)\n\(.*\)$/\1    \2/
  }
  /^\.IP$/d
  /^\.SH EXAMPLES$/a\
.nf
  /^\.S[SH] /{
    /EXAMPLES/!i\
.fi
  }
}
