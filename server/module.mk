# server/module.mk - the daemon seamtexd. Included by the top Makefile.
