/* version.h: the toolkit's version, written into every file header (SOFTWARE=). */
#ifndef PM_VERSION_H
#define PM_VERSION_H

#define PM_VERSION_STRING "0.1.0"

#endif
